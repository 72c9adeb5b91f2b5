#!/usr/bin/env bash
# The shipped recipe of config/models.json (docs/learning.md, "The shipped model file"): render
# the training sequences, label their pairs, train the four models. Renders and the pair table
# are kept in DATA_DIR and reused (delete train.csv after a change to the tracker, the labels
# or the features). Run inside the environment, or let it enter it:
#   scripts/train_models.sh [DATA_DIR] [OUT_MODEL] [initsel train options...]
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ -z "${INITSEL_ENV:-}" ]; then
    exec "$root/scripts/run.sh" bash "$root/scripts/train_models.sh" "$@"
fi
D=${1:-/tmp/initsel-data}
OUT=${2:-$D/models.json}
shift $(( $# > 2 ? 2 : $# ))
mkdir -p "$D"
render() {  # name, then initsel synth options; skipped when already rendered
    local name=$1; shift
    [ -f "$D/$name/.rendered" ] && return 0
    initsel synth --out "$D/$name" --no-progress "$@" >/dev/null
    touch "$D/$name/.rendered"
}
render far_s1 --trajectory far --frames 600 --seed 1
render far_s2 --trajectory far --frames 300 --seed 2
render zigzag_far --scene zigzag --trajectory far --frames 150 --seed 3
render floor_far --scene floor --trajectory far --frames 150 --seed 4
render random_s5 --trajectory random --frames 150 --seed 5
render random_s6 --trajectory random --frames 150 --seed 6
render rotation_s7 --trajectory rotation --frames 90 --seed 7
render static_s8 --trajectory static --frames 60 --seed 8
render forward_s9 --trajectory forward --frames 90 --seed 9
render rotation_s10 --trajectory rotation --frames 180 --seed 10
render static_s14 --scene zigzag --trajectory static --frames 60 --seed 14
names=(far_s1 far_s2 zigzag_far floor_far random_s5 random_s6 rotation_s7 static_s8 forward_s9
       rotation_s10 static_s14)
[ -f "$D/train.csv" ] || initsel dataset "${names[@]/#/$D/}" --out "$D/train.csv" --batch 90 \
    --jobs 2 --quiet
initsel train "$D/train.csv" --out "$OUT" "$@"
echo "wrote $OUT" >&2
