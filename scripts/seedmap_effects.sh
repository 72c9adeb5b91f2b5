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
    [ -f "$X/$name/effects.yaml" ] ||
        initsel synth --out "$X/$name" --strength "$STRENGTH" --no-progress "$@" >/dev/null
}
STRENGTH=${STRENGTH:-default}
case "$STRENGTH" in default | strong) ;; *) echo "STRENGTH must be default or strong" >&2; exit 2 ;; esac
sfx=
if [ "$STRENGTH" = strong ]; then sfx=_strong; fi
# Short names -> effects of initsel_ros.synth.realism.EFFECT_LEVELS, rendered at $STRENGTH.
declare -A FX=(
    [blur]="--effect motion_blur" [rolling]="--effect rolling_shutter"
    [ramp]="--effect exposure_ramp" [vignetting]="--effect vignetting"
    [shot]="--effect noise" [jpeg]="--effect jpeg" [distortion]="--effect distortion"
    [movers]="--effect movers"
)
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
