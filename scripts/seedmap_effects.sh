#!/usr/bin/env bash
# The published seed map under camera effects (docs/robustness.md): render a desk (the near
# trajectory), a wall seen from an arc and a pure pan, with every effect at its default
# strength together and with each effect alone, then judge the selector's initializations
# with `initsel seedmap`. Run inside the environment:
#   scripts/run.sh bash scripts/seedmap_effects.sh [DATA_DIR] [OUT_DIR] [SEEDMAP OPTIONS...]
# Renders are kept in DATA_DIR and reused; OUT_DIR gets one seedmap.md/.csv per run.
# STRENGTH=strong uses the strong strengths of EFFECT_LEVELS instead (renders named *_strong).
set -euo pipefail
X=${1:-/tmp/initsel-effects}
OUT=${2:-$X/seedmap}
shift $(( $# > 2 ? 2 : $# ))
mkdir -p "$X" "$OUT"
render() {  # name, then initsel synth options; skipped when already rendered
    local name=$1; shift
    [ -f "$X/$name/effects.yaml" ] || initsel synth --out "$X/$name" --no-progress "$@" >/dev/null
}
STRENGTH=${STRENGTH:-default}
case "$STRENGTH" in default | strong) ;; *) echo "STRENGTH must be default or strong" >&2; exit 2 ;; esac
# Strengths of initsel_ros.synth.realism.EFFECT_LEVELS.
if [ "$STRENGTH" = strong ]; then
    sfx=_strong
    declare -A FX=(
        [blur]="--exposure-time 0.030"
        [rolling]="--line-delay 6e-5"
        [ramp]="--gain-ramp 0.4,1.8,1"
        [vignetting]="--vignetting 1.0"
        [shot]="--noise 4 --full-well 2500"
        [jpeg]="--jpeg-quality 40"
        [distortion]="--distortion=-0.28,0.08,1e-3,-1e-3"
        [movers]="--movers 4"
    )
else
    sfx=
    declare -A FX=(
        [blur]="--exposure-time 0.010"
        [rolling]="--line-delay 3e-5"
        [ramp]="--gain-ramp 0.6,1.4,2"
        [vignetting]="--vignetting 0.5"
        [shot]="--noise 2 --full-well 10000"
        [jpeg]="--jpeg-quality 80"
        [distortion]="--distortion=-0.15,0.05,5e-4,-5e-4"
        [movers]="--movers 2"
    )
fi
ALL="${FX[shot]} ${FX[blur]} ${FX[rolling]} ${FX[ramp]} ${FX[vignetting]} ${FX[jpeg]} ${FX[distortion]}"
# Every effect together (the scene variants and movers apart).
# shellcheck disable=SC2086
{
render near_all_fx$sfx --trajectory near --frames 300 --start 80 --seed 51 $ALL
render wall_arc_all_fx$sfx --scene wall --trajectory arc --frames 240 --seed 52 $ALL
render rotation_all_fx$sfx --trajectory rotation --frames 120 --seed 53 $ALL
}
initsel seedmap "$X/near_all_fx$sfx" "$X/wall_arc_all_fx$sfx" "$X/rotation_all_fx$sfx" \
    --out-dir "$OUT/all_effects$sfx" "$@" >/dev/null
# Each effect alone: desk (near frames 80-229), wall from an arc (120 frames), pan (90 frames).
for fx in "${!FX[@]}"; do
    # shellcheck disable=SC2086
    {
    render "desk_$fx$sfx" --trajectory near --frames 150 --start 80 --seed 61 ${FX[$fx]}
    render "wall_arc_$fx$sfx" --scene wall --trajectory arc --frames 120 --seed 62 ${FX[$fx]}
    render "rotation_$fx$sfx" --trajectory rotation --frames 90 --seed 63 ${FX[$fx]}
    }
done
# The scene variants (one strength): little texture, repeated texture (a desk and a pan each).
scenes=()
if [ -z "$sfx" ]; then
    scenes=(low_texture repeated)
    for scene in "${scenes[@]}"; do
        render "desk_$scene" --scene "$scene" --trajectory near --frames 150 --start 80 --seed 61
        render "rotation_$scene" --scene "$scene" --trajectory rotation --frames 90 --seed 63
    done
fi
for fx in "${!FX[@]}" "${scenes[@]}"; do
    seqs=("$X/desk_$fx$sfx" "$X/rotation_$fx$sfx")
    [ -d "$X/wall_arc_$fx$sfx" ] && seqs+=("$X/wall_arc_$fx$sfx")
    initsel seedmap "${seqs[@]}" --no-baselines --out-dir "$OUT/$fx$sfx" "$@" >/dev/null
done
echo "seed maps in $OUT/*/seedmap.md"
