#!/usr/bin/env bash
# The recipe of the shipped config/models.json (docs/learning.md, "The shipped model file"):
# render the training sequences and their camera-effects twins, label their pairs, and
# distill config/models_full.json (the tree models on the full feature set) into trees that
# read only the extents and the Gram-matrix moments (the per-frame decision's budget).
# Renders and pair tables are kept in DATA_DIR and reused (delete its CSVs after a change to
# the tracker, the labels or the features). Run inside the environment, or let it enter it:
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
# The training sequences (far-style as in the paper, plus variety)...
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
CLEAN=(far_s1 far_s2 zigzag_far floor_far random_s5 random_s6 rotation_s7 static_s8 forward_s9
       rotation_s10 static_s14)
# ...and the same motions with a camera drawn from each seed (--realism: exposure, noise,
# blur, rolling shutter, ...; docs/synth.md), as scripts/train_effects_mix.sh names them.
render fx_far_s101 --realism --trajectory far --frames 600 --seed 101
render fx_far_s102 --realism --trajectory far --frames 300 --seed 102
render fx_zigzag_far --realism --scene zigzag --trajectory far --frames 150 --seed 103
render fx_floor_far --realism --scene floor --trajectory far --frames 150 --seed 104
render fx_random_s105 --realism --trajectory random --frames 150 --seed 105
render fx_random_s106 --realism --trajectory random --frames 150 --seed 106
render fx_rotation_s107 --realism --trajectory rotation --frames 90 --seed 107
render fx_static_s108 --realism --trajectory static --frames 60 --seed 108
render fx_forward_s109 --realism --trajectory forward --frames 90 --seed 109
render fx_rotation_s110 --realism --trajectory rotation --frames 180 --seed 110
render fx_static_s114 --realism --scene zigzag --trajectory static --frames 60 --seed 114
FX=(fx_far_s101 fx_far_s102 fx_zigzag_far fx_floor_far fx_random_s105 fx_random_s106
    fx_rotation_s107 fx_static_s108 fx_forward_s109 fx_rotation_s110 fx_static_s114)
[ -f "$D/train.csv" ] || initsel dataset "${CLEAN[@]/#/$D/}" --out "$D/train.csv" --batch 90 \
    --jobs 2 --quiet
[ -f "$D/train_fx.csv" ] || initsel dataset "${FX[@]/#/$D/}" --out "$D/train_fx.csv" \
    --batch 90 --jobs 2 --quiet
# ...and the planar-arc family's tuning seeds 0-4 (scripts/planar_arc.sh: planes from sideways
# arcs and slides, pans with sensor noise, moving boards or a focal-length error, a still
# camera with moving boards): where the node must not initialize, the students must say what
# the teacher says, and they only learn that from such pairs.
bash "$root/scripts/planar_arc.sh" render-tune "$D/planar_arc"
ARCS=("$D"/planar_arc/*_s[0-4])
[ -f "$D/train_arcs.csv" ] || initsel dataset "${ARCS[@]}" --out "$D/train_arcs.csv" \
    --batch 35 --jobs 2 --quiet
# The students read the 15 extent and disparity features and the 9 moments; 40 trees of depth 3
# a model, learning rate 0.25: of 30, 40, 60 and 100 trees, the one whose students fitted on
# one half of the pairs (clean or camera effects) agree best with the teacher on the other
# (docs/learning.md, section 4).
initsel train "$D/train.csv" "$D/train_fx.csv" "$D/train_arcs.csv" --distill "$root/config/models_full.json" \
    --trees 40 --learning-rate 0.25 \
    --paper-features count disparity_mean disparity_std x0_min x0_max y0_min y0_max x1_min \
    x1_max y1_min y1_max x0_range y0_range x1_range y1_range \
    --extra-features x_flow_mean_x x_flow_mean_y x_flow_coherence x_flow_spread \
    x_point_spread x_affine_divergence x_affine_curl x_affine_deformation \
    x_homography_dlt_residual \
    --out "$OUT" "$@"
echo "wrote $OUT" >&2
