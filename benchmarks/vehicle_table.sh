#!/usr/bin/env bash
# Localization by vehicle kinematics: a differential drive (wheels 2 % and 2.5 % larger than
# calibrated), a tricycle (drive wheel 2 % larger, steering 0.5 degrees off its calibrated
# zero) and a mecanum vehicle (wheels 2 % larger, rollers slipping 5 % sideways, crabbing up to
# 45 degrees off the path every 4 m, on the mapping lap too, so that its camera sees the lanes
# mapped) on the same network route, its bends eased in over 0.5 m as a tricycle's guide path
# is. Each maps the route in one slow lap, then drives it at 1.5 and 7.2 m/s asked (the bends
# cap the speed) and replays against a map painted at the mapping lap's true poses (what
# the kinematics alone change) and one built from the lap's frames and encoders (what a site
# gets; checked in the built map's own frame, placed on the truth by the mapping report's
# best rigid alignment); dead reckoning beside them. Every row counts wrong fixes (more than
# 1 mm from the truth).
# Usage: [KINDS='mecanum ...'] benchmarks/vehicle_table.sh [MOSAICLOC] [WORK_DIR]
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
mkdir -p "$WORK"
route='route: {network_scale: 0.5, curvature_transition_m: 0.5}'
tricycle='vehicle: {kind: tricycle, drive_wheel_radius_mm: 100.0, wheelbase_mm: 1200.0, ticks_per_revolution: 4096, steering_ticks_per_revolution: 65536}'
mecanum='vehicle: {kind: mecanum, mecanum_wheel_radius_mm: 76.0, track_width_mm: 560.0, wheelbase_mm: 480.0, ticks_per_revolution: 4096}'
crab='route: {network_scale: 0.5, curvature_transition_m: 0.5, crab_amplitude_deg: 45, crab_wavelength_m: 4}'
printf '%s\n' "$route" > "$WORK/differential-map.yaml"
printf '%s\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\n' "$route" > "$WORK/differential-drive.yaml"
printf '%s\n%s\n' "$route" "$tricycle" > "$WORK/tricycle-map.yaml"
printf '%s\n%s\nencoders: {drive_radius_error: 0.02, steering_offset_error_deg: 0.5}\n' "$route" "$tricycle" \
  > "$WORK/tricycle-drive.yaml"
printf '%s\n%s\n' "$crab" "$mecanum" > "$WORK/mecanum-map.yaml"
printf '%s\n%s\nencoders: {mecanum_radius_error: 0.02, lateral_slip: 0.05}\n' "$crab" "$mecanum" > "$WORK/mecanum-drive.yaml"

printf '%-12s %6s %-14s %8s %6s %6s %9s %10s %9s %8s\n' vehicle "m/s" map "fix %" losses wrong "rms mm" "max mm" \
  "NIS in95" "reloc"
for kind in ${KINDS:-differential tricycle mecanum}; do
  "$MOSAICLOC" -q simulate --out "$WORK/$kind-map" --overwrite --config "$WORK/$kind-map.yaml" \
    --route network --laps 1 --speed-mps 0.5 --seed 81 >/dev/null
  "$MOSAICLOC" -q map build --dataset "$WORK/$kind-map" --out "$WORK/$kind-truth.mosaic" --poses groundtruth \
    --overwrite >/dev/null
  "$MOSAICLOC" -q map build --dataset "$WORK/$kind-map" --out "$WORK/$kind-built.mosaic" --overwrite \
    --report "$WORK/$kind-mapping" >/dev/null
  for speed in 1.5 7.2; do
    run="$WORK/$kind-$speed"
    "$MOSAICLOC" -q simulate --out "$run" --overwrite --config "$WORK/$kind-drive.yaml" \
      --route network --laps 1 --speed-mps "$speed" --seed 82 >/dev/null
    for map in truth built dead-reckoning; do
      if [ "$map" = dead-reckoning ]; then
        "$MOSAICLOC" -q replay --dataset "$run" --mode dead-reckoning --out "$run-$map" >/dev/null
      elif [ "$map" = built ]; then
        # The built map has a frame of its own: the truth is checked in it (the mapping
        # report's best rigid alignment), so the wrong fixes are the localization's.
        placement=$(python3 -c 'import json,sys; t=json.load(open(sys.argv[1]))["vs_groundtruth"]["truth_from_map"]; print("%.9f,%.9f,%.12f" % (t["x_mm"], t["y_mm"], t["yaw_deg"]))' \
          "$WORK/$kind-mapping/consistency.json")
        "$MOSAICLOC" -q replay --dataset "$run" --map "$WORK/$kind-$map.mosaic" --out "$run-$map" \
          --truth-from-map="$placement" >/dev/null
      else
        "$MOSAICLOC" -q replay --dataset "$run" --map "$WORK/$kind-$map.mosaic" --out "$run-$map" >/dev/null
      fi
      python3 - "$run-$map/metrics.json" "$kind" "$speed" "$map" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
f = lambda v, fmt: "n/a" if v is None else fmt % v
print("%-12s %6s %-14s %8s %6s %6s %9s %10s %9s %8s" % (
    sys.argv[2], sys.argv[3], sys.argv[4], f(None if m["fix_rate"] is None else 100 * m["fix_rate"], "%.1f"),
    f(m["lock_losses"], "%d"), f(m["wrong_fixes"], "%d"), f(m["position_rms_mm"], "%.4f"),
    f(m["position_max_mm"], "%.3f"), f(m.get("nis_inside_95_share"), "%.3f"), f(m.get("relocalizations"), "%d")))
PY
    done
  done
  python3 - "$WORK/$kind-mapping/consistency.json" "$kind" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
g = c["vs_groundtruth"]
print("%-12s the built map's poses against the truth (best rigid alignment): rms %.3f mm, max %.3f mm, heading rms %.4f deg"
      % (sys.argv[2], g["rms_mm"], g["max_mm"], g["heading_rms_deg"]))
PY
done
echo "datasets and reports in $WORK"
