#!/usr/bin/env bash
# Straight motion toward an oblique wall, where H's two decompositions stay close (issue 20;
# docs/initialization.md, known limits): render the wall approached straight on at 0 and 2
# grey levels of sensor noise, run the selector on 60-frame batches every 30 frames and
# count the batches that publish the swapped decomposition (E_t > 0.3).
#   scripts/straight_wall.sh SEEDS [DATA_DIR] [OUT_DIR]
# SEEDS is a range: 0-4 (where the swap was found and traced), 5-9 and 10-14 (used to choose
# between rules), 15-19 (run once, after the choice). About 1 minute per 5 seeds rendered,
# 1 minute per 5 seeds evaluated (2 cores).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
if [ -z "${INITSEL_ENV:-}" ]; then
    exec "$root/scripts/run.sh" bash "$root/scripts/straight_wall.sh" "$@"
fi
range=${1:?usage: scripts/straight_wall.sh FIRST-LAST [DATA_DIR] [OUT_DIR]}
first=${range%-*}
last=${range#*-}
D=${2:-/tmp/initsel-straight-wall}
OUT=${3:-$D/out/$range}
mkdir -p "$D" "$OUT"
for noise in 0 2; do
    seqs=()
    for seed in $(seq "$first" "$last"); do
        name=wall_forward_n${noise}_s${seed}
        if [ ! -f "$D/$name/.rendered" ]; then
            initsel synth --scene wall --trajectory forward --frames 150 --noise "$noise" \
                --seed "$seed" --out "$D/$name" --no-progress >/dev/null 2>>"$OUT/log.txt"
            touch "$D/$name/.rendered"
        fi
        seqs+=("$D/$name")
    done
    initsel seedmap "${seqs[@]}" --no-baselines --jobs 2 --out-dir "$OUT/noise$noise" \
        >/dev/null 2>>"$OUT/log.txt" || { echo "initsel seedmap failed: see $OUT/log.txt" >&2; exit 1; }
    python - "$OUT/noise$noise/seedmap.csv" "$noise" <<'EOF'
import csv
import sys

rows = [r for r in csv.DictReader(open(sys.argv[1])) if r['system'] == 'initsel']
done = [r for r in rows if r['initialized'] == 'True']
swapped = [r for r in done if float(r['e_t']) > 0.3]
print(f'noise {sys.argv[2]}: {len(swapped)} of {len(done)} initialized batches publish the swap')
for r in swapped:
    print(f"  {r['sequence']} batch {r['start']}: {r['method']}, E_t {float(r['e_t']):.3f}")
EOF
done
echo "seed maps in $OUT/noise0 and $OUT/noise2 (log: $OUT/log.txt)" >&2
