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
# The clean recipe of the shipped file and the same motions, each with a camera drawn from its
# seed (ranges: docs/synth.md).
source "$(dirname "${BASH_SOURCE[0]}")/training_sequences.sh"
render_training_sequences
# Scenes and motions that --realism does not draw: little or repeated texture, and moving
# boards in front of a pure rotation (their motion is parallax no rotation explains).
render fx_low_texture_far --realism --scene low_texture --trajectory far --frames 150 --seed 115
render fx_repeated_far --realism --scene repeated --trajectory far --frames 150 --seed 116
render fx_low_texture_rotation --realism --scene low_texture --trajectory rotation --frames 90 --seed 117
render fx_repeated_rotation --realism --scene repeated --trajectory rotation --frames 90 --seed 118
render fx_movers_rotation --realism --movers 2 --trajectory rotation --frames 120 --seed 119
render fx_movers_far --realism --movers 3 --trajectory far --frames 150 --seed 120
FX=("${TWINS[@]}" fx_low_texture_far fx_repeated_far fx_low_texture_rotation
    fx_repeated_rotation fx_movers_rotation fx_movers_far)
clean_paths=("${CLEAN[@]/#/$D/}")
fx_paths=("${FX[@]/#/$D/}")
[ -f "$D/train.csv" ] || initsel dataset "${clean_paths[@]}" --out "$D/train.csv" --batch 90 --jobs 2
[ -f "$D/train_fx.csv" ] || initsel dataset "${fx_paths[@]}" --out "$D/train_fx.csv" --batch 90 --jobs 2
initsel train "$D/train.csv" "$D/train_fx.csv" --out "$OUT"
initsel train "$D/train.csv" --out "$D/models_clean_retrained.json"
initsel train "$D/train_fx.csv" --out "$D/models_effects_only.json"
