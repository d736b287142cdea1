#!/usr/bin/env bash
# Floors with relief under the camera's ring light: brick (../shared/data) whose joints lie
# DEPTH mm below the brick tops and procedural concrete whose dark parts lie DEPTH/2 mm low,
# lit by 8 LEDs on a 50 mm ring around the lens, 200 mm over the floor, 10 % ambient light.
# For every depth: a loop and a 20 m straight, each mapped at 0.5 m/s (its poses estimated
# from frames and encoders, and, for comparison, painted at the true poses), then the loop
# driven at 1.5 m/s and the straight at 7.2 m/s (3 m/s^2), both with 15 % less light and
# wheels 2 % / 2.5 % larger than calibrated, replayed with the tracker of CONFIG (default: config/default). Every row
# counts wrong fixes (more than 1 mm from the truth; on a self-built map that includes the
# map's own frame error, so "aligned" gives the RMS after the best rigid alignment).
# Usage: benchmarks/relief_table.sh [MOSAICLOC] [WORK_DIR] [DEPTHS] [FLOORS] [CONFIGS]
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
DEPTHS=${3:-0 1 2 3}
FLOORS=${4:-brick procedural}
CONFIGS=${5:-$HERE/config/default/localizer.yaml}
TEXTURES=${MOSAICLOC_SHARED_DATA:-$HERE/../shared/data}/textures
PYTHON=/usr/bin/python3
LIGHT='light: {sources: 8, ring_radius_mm: 50.0, ambient: 0.1}'
DIMMER='light: {sources: 8, ring_radius_mm: 50.0, ambient: 0.1, ring_gain: 0.85}'
WHEELS='encoders: {left_radius_error: 0.02, right_radius_error: 0.025}'
mkdir -p "$WORK"

row() {  # row LABEL REPORT_DIR ALIGNED_RMS
  "$PYTHON" - "$@" <<'PY'
import json, sys
label, rep, aligned = sys.argv[1:4]
try:
    m = json.load(open(rep + "/metrics.json"))
except OSError:
    print(f"{label:<40} no report"); sys.exit()
g = lambda k, f: (f % m[k]) if m.get(k) is not None else "n/a"
print(f"{label:<40} {g('fix_rate','%8.4f')} {g('lock_losses','%6d')} {g('wrong_fixes','%6d')} {g('position_rms_mm','%8.4f')} "
      f"{g('position_max_mm','%8.4f')} {aligned:>8} {g('repeatability_mm','%8.4f')} {g('processing_fps','%7.0f')}")
PY
}

printf '%-40s %8s %6s %6s %8s %8s %8s %8s %7s\n' case fix_rate losses wrong rms_mm max_mm aligned repeat fps
for name in $FLOORS; do
  case $name in
    procedural) floor=procedural; scale=0.5 ;;
    brick) floor="$TEXTURES/brick_floor_1024.png"; scale=1.0
      if [ ! -f "$floor" ]; then echo "brick: no texture at $floor, skipped"; continue; fi ;;
  esac
  for depth in $DEPTHS; do
    d="$WORK/$name-$depth"
    mkdir -p "$d"
    relief=$("$PYTHON" -c "print(f'relief: {{depth_mm: {$depth * $scale}}}')")
    printf '%s\n%s\n' "$relief" "$LIGHT" > "$d/map.yaml"
    printf '%s\n%s\n%s\n' "$relief" "$DIMMER" "$WHEELS" > "$d/drive.yaml"
    printf '%s\n%s\n%s\n%s\n' "$relief" "$DIMMER" "$WHEELS" 'route: {max_accel_mps2: 3.0}' > "$d/fast.yaml"
    for route in loop straight; do
      [ -d "$d/map-$route" ] || "$MOSAICLOC" -q simulate --out "$d/map-$route" --floor "$floor" --route $route --laps 1 \
        --speed-mps 0.5 --seed 21 --config "$d/map.yaml" >/dev/null
      for poses in groundtruth estimate; do
        [ -f "$d/$poses-$route.mosaic" ] || "$MOSAICLOC" -q map build --dataset "$d/map-$route" \
          --out "$d/$poses-$route.mosaic" --poses "$poses" --overwrite >/dev/null
      done
    done
    [ -d "$d/drive" ] || "$MOSAICLOC" -q simulate --out "$d/drive" --floor "$floor" --route loop --laps 1 \
      --speed-mps 1.5 --seed 22 --config "$d/drive.yaml" >/dev/null
    [ -d "$d/fast" ] || "$MOSAICLOC" -q simulate --out "$d/fast" --floor "$floor" --route straight --laps 1 \
      --speed-mps 7.2 --seed 23 --config "$d/fast.yaml" >/dev/null
    for poses in groundtruth estimate; do
      for drive in drive fast; do
        route=loop
        [ $drive = fast ] && route=straight
        for config in $CONFIGS; do
          tag=$(basename "$config" .yaml)
          rep="$d/rep-$poses-$drive-$tag"
          rm -rf "$rep"
          "$MOSAICLOC" -q replay --dataset "$d/$drive" --map "$d/$poses-$route.mosaic" --out "$rep" --config "$config" \
            >/dev/null 2>&1 || true
          al=$("$PYTHON" "$HERE/benchmarks/aligned.py" "$rep/estimate.tum" "$d/$drive/groundtruth/data.tum" 2>/dev/null \
            | cut -d' ' -f1 || echo n/a)
          row "$name $(awk "BEGIN{print $depth * $scale}")mm $poses $drive $tag" "$rep" "${al:-n/a}"
        done
      done
    done
  done
done
