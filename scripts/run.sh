#!/usr/bin/env bash
# Set up a virtual environment with ROS 2 Jazzy from PyPI, then run one job in it.
#   scripts/run.sh demo [ARGS]   main job: render a sequence and initialize on it, live
#   scripts/run.sh test [ARGS]   lint and the whole test suite
#   scripts/run.sh shell         an interactive shell with the environment set
#   scripts/run.sh CMD [ARGS]    any command inside the environment (e.g. initsel --help)
# Environment: INITSEL_VENV (default .venv), PYTHON (default python3).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv=${INITSEL_VENV:-$root/.venv}
case "$venv" in /*) ;; *) venv=$PWD/$venv ;; esac  # a relative INITSEL_VENV: the caller's
python=${PYTHON:-python3}

# A parent ROS-wheels process marks its children; a fresh venv must bootstrap itself.
unset _ROS_WHEELS_BOOTSTRAP_COMPLETE LD_LIBRARY_PATH

stamp="$venv/.initsel-installed"
if [ ! -f "$stamp" ] || [ "$root/setup.py" -nt "$stamp" ]; then
    echo "== setting up $venv (ROS 2 Jazzy wheels, numpy, OpenCV, scikit-learn)" >&2
    [ -x "$venv/bin/python" ] || "$python" -m venv "$venv"
    # (sed drops the notes this machine's pip configuration prints for every package)
    "$venv/bin/python" -m pip install --quiet --upgrade pip 2>&1 | sed '/is ignored: it is neither/d'
    "$venv/bin/python" -m pip install --quiet -e "$root[ros,test,plot,cluster]" 2>&1 \
        | sed '/is ignored: it is neither/d'

    touch "$stamp"
fi

export VIRTUAL_ENV=$venv
export PATH="$venv/bin:$PATH"
export AMENT_PREFIX_PATH=$venv
# Keep DDS discovery on this machine, on a domain of our own. ROS logs go where ROS puts
# them (ROS_LOG_DIR when set, else ~/.ros/log: one file per process), not to a new folder
# per call.
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
export ROS_DOMAIN_ID=${ROS_DOMAIN_ID:-$(( RANDOM % 100 + 100 ))}
# Shared-memory segment large enough for full camera frames (see README, Transport).
export INITSEL_ENV=1
export FASTRTPS_DEFAULT_PROFILES_FILE=${FASTRTPS_DEFAULT_PROFILES_FILE:-$root/config/fastdds_shm.xml}

# Commands run in the caller's directory (relative paths mean what they say); the tests in
# the project's.
job=${1:-demo}
[ $# -gt 0 ] && shift
case "$job" in
    demo) exec initsel demo "$@" ;;
    test)
        cd "$root"
        ruff check initsel_ros test
        ruff format --check initsel_ros test
        exec python -m pytest -q "$@" test ;;
    shell) exec "${SHELL:-bash}" -i ;;
    *) exec "$job" "$@" ;;
esac
