#!/usr/bin/env bash
# The localization target tables, on procedural concrete and the real textures of
# ../shared/data, with wheels 2 % and 2.5 % larger than calibrated (and the simulator's slip).
#  straight: for each speed (half and three times the overlap speed limit at 30 Hz), map the
#    floor with a slow 30 m run, drive it with other noise, and replay with the mosaic, with
#    dead reckoning only and with frame-to-frame visual odometry only.
#  excursion: map a network of lanes in one slow lap, drive two laps that take lanes the map
#    does not have (1.5 m/s and 7.2 m/s asked; the route's turns cap the speed), and replay
#    with the mosaic: wrong fixes, the frames off the map and the returns onto it.
# Every row counts wrong fixes (more than 1 mm from the truth): a lock never lost proves
# nothing if it held onto the wrong place.
# Usage: benchmarks/localization_table.sh [MOSAICLOC] [WORK_DIR] [TABLES]   (prints the tables;
#        TABLES: "straight excursion", the default, or either)
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
TABLES=${3:-straight excursion}
TEXTURES=${MOSAICLOC_SHARED_DATA:-$HERE/../shared/data}/textures
mkdir -p "$WORK"
printf 'route: {straight_length_m: 30.0, max_accel_mps2: 3.0}\n' > "$WORK/route.yaml"
printf 'route: {straight_length_m: 30.0, max_accel_mps2: 3.0}\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\n' \
  > "$WORK/drive.yaml"

floors=("procedural")
for t in asphalt_02_2048.jpg brick_floor_1024.png; do
  [ -f "$TEXTURES/$t" ] && floors+=("$TEXTURES/$t")
done

if [[ " $TABLES " == *" straight "* ]]; then
printf '%-12s %6s %-16s %8s %6s %6s %10s %10s %10s %9s %9s\n' floor "m/s" mode "fix %" losses wrong "rms mm" "max mm" "head° rms" "p50 ms" "p99 ms"
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
print("%-12s %6s %-16s %8s %6s %6s %10s %10s %10s %9s %9s" % (
    sys.argv[2], sys.argv[3], sys.argv[4], f(None if m["fix_rate"] is None else 100 * m["fix_rate"], "%.1f"),
    f(m["lock_losses"], "%d"), f(m["wrong_fixes"], "%d"), f(m["position_rms_mm"], "%.4f"), f(m["position_max_mm"], "%.4f"),
    f(m["heading_rms_deg"], "%.4f"), f(m["latency_p50_ms"], "%.2f"), f(m["latency_p99_ms"], "%.2f")))
PY
    done
  done
done
echo "overlap speed limit at 30 Hz with beta = 0.5: 2.4 m/s"
fi

if [[ " $TABLES " == *" excursion "* ]]; then
printf 'route: {network_scale: 0.5}\n' > "$WORK/network.yaml"
printf 'route: {network_scale: 0.5}\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\n' \
  > "$WORK/network-drive.yaml"
echo
printf '%-12s %6s %8s %6s %6s %9s %8s %9s %7s %7s %10s %10s %9s\n' floor "top m/s" "fix %" losses wrong \
  "worst mm" "off-map" "DR max mm" returns "to fix" "1st fix mm" "fix rms mm" "p99 ms"
for floor in "${floors[@]}"; do
  name=$(basename "$floor"); name=${name%%_*}; name=${name%%.*}
  "$MOSAICLOC" -q simulate --out "$WORK/$name-network-map" --overwrite --config "$WORK/network.yaml" --floor "$floor" \
    --route network --laps 1 --speed-mps 0.5 --seed 81 >/dev/null
  "$MOSAICLOC" -q map build --dataset "$WORK/$name-network-map" --out "$WORK/$name-network.mosaic" --overwrite >/dev/null
  for speed in 1.5 7.2; do
    run="$WORK/$name-network-$speed"
    "$MOSAICLOC" -q simulate --out "$run" --overwrite --config "$WORK/network-drive.yaml" --floor "$floor" \
      --route network --laps 2 --speed-mps "$speed" --seed 82 >/dev/null
    "$MOSAICLOC" -q replay --dataset "$run" --map "$WORK/$name-network.mosaic" --out "$run-mosaic" >/dev/null
    python3 - "$run-mosaic" "$name" <<'PY'
import json, sys
report, name = sys.argv[1:3]
m = json.load(open(report + "/metrics.json"))
f = lambda v, fmt: "n/a" if v is None else fmt % v
print("%-12s %6s %8s %6s %6s %9s %8s %9s %7s %7s %10s %10s %9s" % (
    name, f(m["max_speed_mps"], "%.2f"), f(100 * m["fix_rate"], "%.1f"), f(m["lock_losses"], "%d"),
    f(m["wrong_fixes"], "%d"), f(m["max_wrong_fix_mm"], "%.1f"), f(m["off_map_frames"], "%d"),
    f(m["off_map_max_error_mm"], "%.2f"), f(m["reentries"], "%d"), f(m["reentry_frames_to_fix_max"], "%d"),
    f(m["reentry_first_fix_error_max_mm"], "%.4f"), f(m["fix_error_rms_mm"], "%.4f"), f(m["latency_p99_ms"], "%.2f")))
PY
  done
done
echo "excursion: 'to fix' and '1st fix mm' are the most frames from a return onto the map to the first fix and"
echo "the largest error of those first fixes; 'DR max mm' the worst dead-reckoning error off the map"
fi
echo "datasets and reports in $WORK"
