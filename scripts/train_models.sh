#!/usr/bin/env bash
# The recipe of the shipped config/models.json (docs/learning.md, "The shipped model file"):
# render the training sequences, their camera-effects twins and the planar-arc tuning set,
# label their pairs, and distill config/models_full.json (the tree models on the full feature
# set) into trees that read only the extents and the Gram-matrix moments (the per-frame
# decision's budget).
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
# The training sequences (CLEAN), their camera-effects twins (TWINS) and the planar-arc
# family's tuning seeds 0-4 (scripts/planar_arc.sh: planes from sideways arcs and slides, pans
# with sensor noise, moving boards or a focal-length error, a still camera with moving
# boards): where the node must not initialize, the students must say what the teacher says,
# and they only learn that from such pairs. make_training_tables labels them.
source "$root/scripts/training_sequences.sh"
make_training_tables
# Random two-view geometries (no images, no labels; learn/twoview.py): 18,000 pairs over the
# motions, scenes, cameras and noise a tracker can meet, so that the students imitate the
# teacher beyond the rendered trajectories too. Of 6,000-36,000 pairs (seeds 11-16), 18,000
# is where the students' agreement with the teacher stops rising, on held-out rendered
# sequences and on held-out two-view pairs together (docs/learning.md, section 5).
[ -f "$D/distill_twoview.csv" ] || initsel twoview --pairs 6000 --seed 11 12 13 \
    --out "$D/distill_twoview.csv"
# The students read the 15 extent and disparity features and the 9 moments; 40 trees of depth 3
# a model, learning rate 0.25: of 30, 40, 60 and 100 trees, the one whose students fitted on
# one half of the pairs (clean or camera effects) agree best with the teacher on the other
# (docs/learning.md, section 4).
initsel train "$D/train.csv" "$D/distill_twins.csv" "$D/distill_arcs.csv" \
    "$D/distill_twoview.csv" \
    --distill "$root/config/models_full.json" --trees 40 --learning-rate 0.25 \
    --paper-features count disparity_mean disparity_std x0_min x0_max y0_min y0_max x1_min \
    x1_max y1_min y1_max x0_range y0_range x1_range y1_range \
    --extra-features x_flow_mean_x x_flow_mean_y x_flow_coherence x_flow_spread \
    x_point_spread x_affine_divergence x_affine_curl x_affine_deformation \
    x_homography_dlt_residual \
    --out "$OUT" "$@"
echo "wrote $OUT" >&2
