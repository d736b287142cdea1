#!/usr/bin/env bash
# Automatic mapping from an empty map (design.md section 7d): lap 1 of a route at 0.5 m/s is
# replayed with --mapping into a new map (visual odometry off the map, stretches closed onto the
# floor already mapped), then a lap at 1.5 m/s and one asking 7.2 m/s (the simulator caps the
# speed at the route's curvature) are localized on the map lap 1 made. Wheels 2 % and 2.5 %
# larger than calibrated on every lap, the simulator's slip.
#  Each case is ROUTE:FLOOR (the network route at scale 1.0, 85 m, or the serpentine survey;
#  procedural concrete, asphalt or the repeating brick of ../shared/data).
#  Map columns: the painted keyframes' poses against the truth (RMS, max; then after the best
#  rigid alignment), stretches committed / closed onto the map / bridged across a break in the
#  chain, keyframes painted, the largest correction a return made.
#  Drive columns: fix rate, lock losses, the fixes after the best rigid alignment (the map's
#  frame taken out: the report's wrong-fix count includes the map's own offset), the camera's
#  repeatability, and the frames without a fix by reason.
# Usage: benchmarks/automatic_mapping_table.sh [MOSAICLOC] [WORK_DIR] [CASES]
#        CASES default "network:procedural"
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
CASES=${3:-network:procedural}
source "$HERE/benchmarks/table_lib.sh"
mkdir -p "$WORK"

# config ROUTE SPEED SEED: a simulator.yaml
config() {
  printf 'route: {name: %s, network_scale: 1.0, speed_mps: %s}\nrun: {laps: 1, seed: %s}\n%s\n' "$1" "$2" "$3" \
    'encoders: {left_radius_error: 0.02, right_radius_error: 0.025}'
}

printf '%-22s %8s %8s %8s %8s %12s %6s %7s | %-5s %8s %6s %8s %8s  %s\n' case pose_rms pose_max al_rms al_max \
  stretches keyfr corr_mm drive fix% losses al_rms repeat "no fix"
for case in $CASES; do
  table_case "$case" || continue
  D="$WORK/$route-$floor"
  mkdir -p "$D"
  config "$route" 0.5 81 > "$D/lap1.yaml"
  config "$route" 1.5 82 > "$D/d1.5.yaml"
  config "$route" 7.2 83 > "$D/d7.2.yaml"
  for run in lap1 d1.5 d7.2; do
    [ -d "$D/$run" ] || "$MOSAICLOC" --quiet simulate --out "$D/$run" --config "$D/$run.yaml" --floor "$floor_arg" \
      >/dev/null
  done
  rm -rf "$D/site.mosaic" "$D/mapped" "$D"/replay-*
  "$MOSAICLOC" --quiet replay --dataset "$D/lap1" --map "$D/site.mosaic" --mapping --out "$D/mapped" >/dev/null
  map=$(aligned "$D/mapped/mapped.tum" "$D/lap1/groundtruth/data.tum")
  for drive in d1.5 d7.2; do
    rep="$D/replay-$drive"
    "$MOSAICLOC" --quiet replay --dataset "$D/$drive" --map "$D/site.mosaic" --out "$rep" >/dev/null
    al=$(aligned "$rep/estimate.tum" "$D/$drive/groundtruth/data.tum" | cut -d' ' -f1)
    "$PYTHON" - "$case" "$map" "$D/mapped/metrics.json" "$drive" "$rep/metrics.json" "$al" <<'PY'
import json, sys
case, mapped, map_metrics, drive, drive_metrics, al = sys.argv[1:7]
m = json.load(open(map_metrics))
d = json.load(open(drive_metrics))
a = mapped.split()
stretches = f"{m['map_extension_segments']}/{m['map_extension_closed']}/{m.get('map_extension_bridged', 0)}"
print(f"{case:<22} {m['map_extension_pose_rms_mm']:8.4f} {m['map_extension_pose_max_mm']:8.4f} {float(a[0]):8.4f} "
      f"{float(a[1]):8.4f} {stretches:>12} {m['map_extension_keyframes']:6d} {m['map_extension_closure_max_mm']:7.3f} | "
      f"{drive:<5} {100 * d['fix_rate']:8.3f} {d['lock_losses']:6d} {float(al):8.4f} "
      f"{d['repeatability_camera_mm']:8.4f}  {d.get('no_fix_reasons') or {}}")
PY
  done
done
