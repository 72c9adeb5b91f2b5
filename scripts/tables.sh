#!/usr/bin/env bash
# Reproduce a README results table from a fresh clone: render what it needs, run, write the
# Markdown the README quotes.
#   scripts/tables.sh seedmap    [DATA_DIR] [OUT_DIR] [initsel seedmap options...]
#   scripts/tables.sh protocol   [DATA_DIR] [OUT_DIR]
#   scripts/tables.sh robustness [DATA_DIR] [OUT_DIR]
#   scripts/tables.sh real       [DATA_DIR] [OUT_DIR]   (sets up the ORB-SLAM3 venv when absent)
#   scripts/tables.sh generalization [DATA_DIR] [OUT_DIR] [initsel train options...]
# Renders are kept in DATA_DIR (default /tmp/initsel-tables) and reused; OUT_DIR (default
# DATA_DIR/out) gets TABLE/*.md (+ CSVs). The script sets up and enters the project's
# environment through scripts/run.sh when it is not already inside it.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ -z "${INITSEL_ENV:-}" ]; then
    exec "$root/scripts/run.sh" bash "$root/scripts/tables.sh" "$@"
fi
table=${1:?usage: scripts/tables.sh seedmap|protocol|robustness|real|generalization [DATA_DIR] [OUT_DIR]}
D=${2:-/tmp/initsel-tables}
OUT=${3:-$D/out}
shift $(( $# > 3 ? 3 : $# ))
mkdir -p "$D" "$OUT"
render() {  # name, then initsel synth options; skipped when already rendered
    local name=$1; shift
    [ -f "$D/$name/groundtruth.txt" ] && [ -f "$D/$name/.rendered" ] && return 0
    initsel synth --out "$D/$name" --no-progress "$@" >/dev/null
    touch "$D/$name/.rendered"
}
# The test sequences of docs/learning.md (never trained on).
test_sequences() {
    render near_test --trajectory near --frames 1000 --seed 11
    render rotation_test --trajectory rotation --frames 120 --seed 12
    render static_test --trajectory static --frames 60 --seed 13
}
# The seed-map sequences: the test sequences plus three planar ones, grouped explicitly (a
# renamed folder keeps its group).
seedmap_sequences() {
    test_sequences
    render wall_arc_test --scene wall --trajectory arc --frames 300 --seed 21
    render wall_forward_test --scene wall --trajectory forward --frames 300 --seed 22
    render floor_near_test --scene floor --trajectory near --frames 300 --start 80 --seed 23
    seqs=("$D/wall_arc_test" "$D/wall_forward_test" "$D/floor_near_test" \
        "$D/near_test" "$D/rotation_test" "$D/static_test")
    groups=(--group wall_arc_test=planar --group wall_forward_test=planar \
        --group floor_near_test=planar --group near_test=non-planar \
        --group rotation_test=rotation/static --group static_test=rotation/static)
}
case "$table" in
    seedmap)  # README "The seed map a SLAM front end receives" (4.5 minutes fresh, 2.5 rendered)
        seedmap_sequences
        initsel seedmap "${seqs[@]}" "${groups[@]}" --out-dir "$OUT/seedmap" "$@"
        echo "wrote $OUT/seedmap/seedmap.md" >&2
        ;;
    real)  # README "Against the real ORB-SLAM3 and COLMAP" (7-18 minutes with the renders kept,
        # by load: a fifth clean, the rest the 3 noise seeds; 2 cores at load 3-13)
        seedmap_sequences
        bash "$root/scripts/setup_orbslam3.sh"  # once: the venv and its vocabulary
        initsel seedmap "${seqs[@]}" "${groups[@]}" --baselines orbslam3,colmap \
            --jobs 2 --out-dir "$OUT/real" "$@"
        initsel seedmap "${seqs[@]}" "${groups[@]}" --baselines orbslam3,colmap \
            --sensor-noise 2 --noise-seed 1 2 3 --jobs 2 --out-dir "$OUT/real_noise" "$@"
        echo "wrote $OUT/real/seedmap.md and $OUT/real_noise/seedmap.md" >&2
        ;;
    protocol)  # README "Results against the paper and the baselines" (about 2 minutes here)
        test_sequences
        # the pair table depends on the code (labels, features): made afresh in OUT each time
        mkdir -p "$OUT/protocol"
        # (with the fire path's outcome: the row of H by the fire path)
        initsel dataset "$D/near_test" "$D/rotation_test" "$D/static_test" \
            --out "$OUT/protocol/test.csv" --batch 30 --jobs 2 --quiet --fire-path
        initsel eval "$OUT/protocol/test.csv" --out-dir "$OUT/protocol" --no-plots "$@" >/dev/null
        echo "wrote $OUT/protocol/eval.md" >&2
        ;;
    robustness)  # docs/robustness.md: the seed map under camera effects (about 10 minutes)
        bash "$root/scripts/seedmap_effects.sh" "$D/effects" "$OUT/robustness" "$@"
        echo "wrote $OUT/robustness/*/seedmap.md" >&2
        ;;
    generalization)  # README "Generalization" (issue 21; about 35 minutes fresh, 6 with the
        # pair tables kept): every scene family of config/families.yaml left out in turn;
        # the tables hold the fire path's outcome, for the row of H by the fire path
        export DATASET_OPTIONS=--fire-path
        source "$root/scripts/training_sequences.sh"
        make_training_tables  # the shipped recipe's tables, in DATA_DIR
        bash "$root/scripts/storeroom_family.sh" "$D"  # the second rendering style
        mkdir -p "$OUT/generalization"
        initsel train "$D/train.csv" "$D/distill_twins.csv" "$D/distill_arcs.csv" \
            "$D/storeroom.csv" --family trees+extra --trees 40 --folds 3 \
            --threshold-prior 0.25 --threshold-prior R=0.15 --family-cap 1000 \
            --rotation-min-static-share 0.95 \
            --leave-family-out "$root/config/families.yaml" \
            --out "$OUT/generalization/generalization.md" "$@" >/dev/null
        echo "wrote $OUT/generalization/generalization.md" >&2
        ;;
    *) echo "unknown table $table: seedmap, protocol, robustness, real or generalization" >&2
       exit 2 ;;
esac
