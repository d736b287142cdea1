#!/usr/bin/env bash
# The localization target table: for each floor (procedural concrete and the real textures
# of ../shared/data) and each speed (half and three times the overlap speed limit at 30 Hz),
# map the floor with a slow 30 m run, drive it with other noise and with wheels 2 % and 2.5 %
# larger than calibrated (and the simulator's slip), and replay with the mosaic, with dead
# reckoning only and with frame-to-frame visual odometry only.
# Usage: benchmarks/localization_table.sh [MOSAICLOC] [WORK_DIR]   (prints a table)
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
TEXTURES=${MOSAICLOC_SHARED_DATA:-$HERE/../shared/data}/textures
mkdir -p "$WORK"
printf 'route: {straight_length_m: 30.0, max_accel_mps2: 3.0}\n' > "$WORK/route.yaml"
printf 'route: {straight_length_m: 30.0, max_accel_mps2: 3.0}\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\n' \
  > "$WORK/drive.yaml"

floors=("procedural")
for t in asphalt_02_2048.jpg brick_floor_1024.png; do
  [ -f "$TEXTURES/$t" ] && floors+=("$TEXTURES/$t")
done

printf '%-12s %6s %-16s %8s %6s %10s %10s %10s %9s %9s\n' floor "m/s" mode "fix %" losses "rms mm" "max mm" "head° rms" "p50 ms" "p99 ms"
for floor in "${floors[@]}"; do
  name=$(basename "$floor"); name=${name%%_*}; name=${name%%.*}
  "$MOSAICLOC" -q simulate --out "$WORK/$name-map" --overwrite --config "$WORK/route.yaml" --floor "$floor" \
    --route straight --laps 1 --speed-mps 0.6 --seed 31 >/dev/null
  "$MOSAICLOC" -q map build --dataset "$WORK/$name-map" --out "$WORK/$name.mosaic" --overwrite >/dev/null
  for speed in 1.2 7.2; do
    "$MOSAICLOC" -q simulate --out "$WORK/$name-$speed" --overwrite --config "$WORK/drive.yaml" --floor "$floor" \
      --route straight --laps 1 --speed-mps "$speed" --seed 32 >/dev/null
    for mode in mosaic dead-reckoning visual-odometry; do
      map_args=()
      [ "$mode" = mosaic ] && map_args=(--map "$WORK/$name.mosaic")
      "$MOSAICLOC" -q replay --dataset "$WORK/$name-$speed" "${map_args[@]}" --mode "$mode" \
        --out "$WORK/$name-$speed-$mode" >/dev/null
      python3 - "$WORK/$name-$speed-$mode/metrics.json" "$name" "$speed" "$mode" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
f = lambda v, fmt: "n/a" if v is None else fmt % v
print("%-12s %6s %-16s %8s %6s %10s %10s %10s %9s %9s" % (
    sys.argv[2], sys.argv[3], sys.argv[4], f(None if m["fix_rate"] is None else 100 * m["fix_rate"], "%.1f"),
    f(m["lock_losses"], "%d"), f(m["position_rms_mm"], "%.4f"), f(m["position_max_mm"], "%.4f"),
    f(m["heading_rms_deg"], "%.4f"), f(m["latency_p50_ms"], "%.2f"), f(m["latency_p99_ms"], "%.2f")))
PY
    done
  done
done
echo "overlap speed limit at 30 Hz with beta = 0.5: 2.4 m/s; datasets and reports in $WORK"
