#!/usr/bin/env bash
# The storeroom family of issue 21: the second rendering style (shaded boxes, brick, stone
# and wood at 0.5-10 m, shot noise and vignetting, fields of view of 50-95 degrees and the
# EuRoC and KITTI image sizes), a stand-in for a renderer the models never saw. Renders the
# sequences and labels their pairs into DATA_DIR/storeroom.csv, for
# `initsel train ... --leave-family-out config/families.yaml` (docs/learning.md, section 7).
#   scripts/storeroom_family.sh [DATA_DIR]        (default /tmp/initsel-data; ~5 minutes)
# Renders and the table are kept and reused; delete the CSV after a change to the labels.
# DATASET_OPTIONS: more `initsel dataset` options (e.g. --fire-path).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ -z "${INITSEL_ENV:-}" ]; then
    exec "$root/scripts/run.sh" bash "$root/scripts/storeroom_family.sh" "$@"
fi
D=${1:-/tmp/initsel-data}
mkdir -p "$D"
render() {  # name, then initsel synth options; skipped when already rendered
    local name=$1; shift
    [ -f "$D/$name/effects.yaml" ] || initsel synth --out "$D/$name" --scene storeroom \
        --no-progress "$@" >/dev/null
}
# every trajectory kind of the first style, each with its own sensor: shot noise of a small
# (6,000 e-) to a mid-size (15,000 e-) pixel, read noise 0.8-2 grey levels, vignetting
render store_far_s201 --trajectory far --frames 300 --seed 201 --full-well 9000 --noise 1.2 \
    --vignetting 0.4
render store_random_s202 --trajectory random --frames 150 --seed 202 --hfov 50 \
    --full-well 15000 --noise 0.8 --vignetting 0.2
render store_random_s203 --trajectory random --frames 150 --seed 203 --hfov 90 \
    --full-well 6000 --noise 2 --vignetting 0.5
render store_forward_s204 --trajectory forward --frames 90 --seed 204 --hfov 75 \
    --full-well 9000 --noise 1.5 --vignetting 0.3
render store_rotation_s205 --trajectory rotation --frames 120 --seed 205 --hfov 95 \
    --full-well 6000 --noise 1.5 --vignetting 0.5
render store_static_s206 --trajectory static --frames 60 --seed 206 --full-well 9000 \
    --noise 1.2 --vignetting 0.4
render store_arc_s207 --trajectory arc --arc-distance 2.5 --arc-extent 0.4 --frames 90 \
    --seed 207 --hfov 70 --full-well 12000 --noise 1 --vignetting 0.3
# EuRoC's (752x480, 79 degrees) and KITTI's (1241x376, 82 degrees) image sizes
render store_random_euroc_s208 --trajectory random --frames 150 --seed 208 --width 752 \
    --height 480 --hfov 79 --full-well 8000 --noise 1.5 --vignetting 0.3
render store_far_kitti_s209 --trajectory far --frames 150 --start 300 --seed 209 \
    --width 1241 --height 376 --hfov 82 --full-well 12000 --noise 1 --vignetting 0.2
SEQS=(store_far_s201 store_random_s202 store_random_s203 store_forward_s204 store_rotation_s205
      store_static_s206 store_arc_s207 store_random_euroc_s208 store_far_kitti_s209)
[ -f "$D/storeroom.csv" ] || initsel dataset "${SEQS[@]/#/$D/}" --out "$D/storeroom.csv" \
    --batch 30 --jobs 2 --quiet ${DATASET_OPTIONS:-}
echo "wrote $D/storeroom.csv" >&2
