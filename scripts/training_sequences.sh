# The training sequences of the shipped models, sourced by scripts/train_models.sh and
# scripts/train_effects_mix.sh (not run on its own). Needs D (the data folder) and the
# environment; defines render and, once render_training_sequences has run, CLEAN (the clean
# recipe: far-style as in the paper, plus variety) and TWINS (the same motions with a camera
# drawn from each seed: --realism, docs/synth.md).
render() {  # name, then initsel synth options; skipped when already rendered (effects.yaml
            # is the last file synth writes). Delete DATA_DIR, or its CSVs, to redo them.
    local name=$1; shift
    [ -f "$D/$name/effects.yaml" ] || initsel synth --out "$D/$name" --no-progress "$@" >/dev/null
}
render_training_sequences() {
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
    CLEAN=(far_s1 far_s2 zigzag_far floor_far random_s5 random_s6 rotation_s7 static_s8
           forward_s9 rotation_s10 static_s14)
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
    TWINS=(fx_far_s101 fx_far_s102 fx_zigzag_far fx_floor_far fx_random_s105 fx_random_s106
           fx_rotation_s107 fx_static_s108 fx_forward_s109 fx_rotation_s110 fx_static_s114)
}
make_training_tables() {  # the pair tables of the shipped recipe in $D (each kept when there):
    # train.csv (CLEAN), distill_twins.csv (TWINS) and distill_arcs.csv (the planar-arc
    # family's tuning seeds 0-4, scripts/planar_arc.sh); needs $root, the project's root.
    # DATASET_OPTIONS: more `initsel dataset` options (scripts/tables.sh generalization:
    # --fire-path)
    render_training_sequences
    [ -f "$D/train.csv" ] || initsel dataset "${CLEAN[@]/#/$D/}" --out "$D/train.csv" \
        --batch 90 --jobs 2 --quiet ${DATASET_OPTIONS:-}
    [ -f "$D/distill_twins.csv" ] || initsel dataset "${TWINS[@]/#/$D/}" \
        --out "$D/distill_twins.csv" --batch 90 --jobs 2 --quiet ${DATASET_OPTIONS:-}
    bash "$root/scripts/planar_arc.sh" render-tune "$D/planar_arc"
    local arcs=("$D"/planar_arc/*_s[0-4])
    [ -f "$D/distill_arcs.csv" ] || initsel dataset "${arcs[@]}" --out "$D/distill_arcs.csv" \
        --batch 35 --jobs 2 --quiet ${DATASET_OPTIONS:-}
}
