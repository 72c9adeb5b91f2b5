#!/usr/bin/env bash
# Render the training sequences of config/models.json twice: clean (the recipe of
# docs/learning.md, section 4) and with a random camera each (--realism, domain
# randomization), plus low-texture, repeated-texture and moving-object sequences; label the
# pairs and train the effects-mix model file, plus the two files it is compared with in
# docs/robustness.md (the clean recipe retrained, the effect sequences alone). Run inside the
# environment:
#   scripts/run.sh bash scripts/train_effects_mix.sh [DATA_DIR] [OUT_MODEL]
set -euo pipefail
D=${1:-/tmp/initsel-data}
OUT=${2:-$D/models_effects_mix.json}
mkdir -p "$D"
render() {  # name, then initsel synth options; skipped when already rendered (effects.yaml
            # is the last file synth writes). Delete DATA_DIR, or its CSVs, to redo them.
    local name=$1; shift
    [ -f "$D/$name/effects.yaml" ] || initsel synth --out "$D/$name" --no-progress "$@"
}
# The clean recipe of the shipped file.
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
# The same motions, each with a camera drawn from its seed (ranges: docs/synth.md).
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
# Scenes and motions that --realism does not draw: little or repeated texture, and moving
# boards in front of a pure rotation (their motion is parallax no rotation explains).
render fx_low_texture_far --realism --scene low_texture --trajectory far --frames 150 --seed 115
render fx_repeated_far --realism --scene repeated --trajectory far --frames 150 --seed 116
render fx_low_texture_rotation --realism --scene low_texture --trajectory rotation --frames 90 --seed 117
render fx_repeated_rotation --realism --scene repeated --trajectory rotation --frames 90 --seed 118
render fx_movers_rotation --realism --movers 2 --trajectory rotation --frames 120 --seed 119
render fx_movers_far --realism --movers 3 --trajectory far --frames 150 --seed 120
FX=(fx_far_s101 fx_far_s102 fx_zigzag_far fx_floor_far fx_random_s105 fx_random_s106
    fx_rotation_s107 fx_static_s108 fx_forward_s109 fx_rotation_s110 fx_static_s114
    fx_low_texture_far fx_repeated_far fx_low_texture_rotation fx_repeated_rotation
    fx_movers_rotation fx_movers_far)
clean_paths=("${CLEAN[@]/#/$D/}")
fx_paths=("${FX[@]/#/$D/}")
[ -f "$D/train.csv" ] || initsel dataset "${clean_paths[@]}" --out "$D/train.csv" --batch 90 --jobs 2
[ -f "$D/train_fx.csv" ] || initsel dataset "${fx_paths[@]}" --out "$D/train_fx.csv" --batch 90 --jobs 2
initsel train "$D/train.csv" "$D/train_fx.csv" --out "$OUT"
initsel train "$D/train.csv" --out "$D/models_clean_retrained.json"
initsel train "$D/train_fx.csv" --out "$D/models_effects_only.json"
