#!/usr/bin/env bash
# Make the separate venv of the real ORB-SLAM3 baseline (initsel seedmap --baselines orbslam3).
#   scripts/setup_orbslam3.sh [VENV]      (default .venv-orbslam3 in the repository)
# orbslam3-python (GPL-3, the ORB-SLAM3 v1.0 monocular system) depends on opencv-python, which
# clashes with the opencv-python-headless of the project's own environment, so it gets a venv
# of its own; initsel seedmap runs it as a subprocess. The script then trains the substitute
# vocabulary ORB-SLAM3 needs (VENV/initsel_orbvoc.txt) from a small render of the project's own
# (about 1 minute in all after the download).
# Environment: PYTHON (default python3; orbslam3-python has cp311 and cp312 wheels).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv=$(realpath -m "${1:-$root/.venv-orbslam3}")
python=${PYTHON:-python3}
# The ROS wheels' library path and bootstrap marker must not leak into the other venv.
unset LD_LIBRARY_PATH _ROS_WHEELS_BOOTSTRAP_COMPLETE PYTHONPATH
if [ ! -f "$venv/.orbslam3-installed" ]; then
    echo "== setting up $venv (orbslam3-python 2.0.0)" >&2
    [ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
    "$venv/bin/python" -m pip install --quiet --upgrade pip 2>&1 | sed '/is ignored: it is neither/d'
    "$venv/bin/python" -m pip install --quiet 'orbslam3-python==2.0.0' 2>&1 \
        | sed '/is ignored: it is neither/d'
    "$venv/bin/python" -c 'import orbslam3' || { echo "orbslam3 does not import in $venv" >&2; exit 1; }
    touch "$venv/.orbslam3-installed"
fi
vocab="$venv/initsel_orbvoc.txt"
if [ ! -f "$vocab" ]; then
    echo "== training the substitute vocabulary $vocab" >&2
    render=$(mktemp -d -t initsel-orbvocab.XXXXXX)
    trap 'rm -rf "$render"' EXIT
    "$root/scripts/run.sh" initsel synth --out "$render/desk" --trajectory near --frames 200 \
        --seed 31 --no-progress >/dev/null
    "$root/scripts/run.sh" initsel synth --out "$render/wall" --scene wall --trajectory arc \
        --frames 200 --seed 32 --no-progress >/dev/null
    "$root/scripts/run.sh" initsel orbvocab "$render/desk" "$render/wall" --out "$vocab"
fi
echo "ORB-SLAM3 baseline ready: $venv (vocabulary $vocab)" >&2
