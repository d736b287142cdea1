#!/usr/bin/env bash
# Figures without ground truth against the truth: on the 85 m network route, two laps at 1.5 and
# at 7.2 m/s asked (the turns cap the speed) over procedural concrete and the real textures of
# ../shared/data, localized on a map built from a slow mapping lap (the frames and encoders
# alone). The drive's second lap takes lanes the mapping lap did not, so it leaves the map.
# Each drive is replayed twice: with its ground truth, and from a copy without it (as a real
# recording is). The repeatability measured from the revisits alone (the copy's report) is
# compared with the truth's at the same point (the camera's centre) over the same frames; the
# truth's repeatability at the vehicle's origin and the filter's consistency (NIS) beside them.
# A self-built map's frame is the truth's up to a small rigid offset, so the fixes are checked
# after the best rigid alignment (benchmarks/aligned.py): a wrong fix shows as a large maximum;
# the truth's figures are taken in the map's frame that alignment gives (replay
# --truth-from-map).
# Usage: benchmarks/validation_table.sh [MOSAICLOC] [WORK_DIR] [FLOORS]
#        (FLOORS: "procedural asphalt brick", the default, or some of them)
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
FLOORS=${3:-procedural asphalt brick}
TEXTURES=${MOSAICLOC_SHARED_DATA:-$HERE/../shared/data}/textures
PYTHON=/usr/bin/python3
mkdir -p "$WORK"
declare -A TEXTURE=([procedural]=procedural [asphalt]="$TEXTURES/asphalt_02_2048.jpg" [brick]="$TEXTURES/brick_floor_1024.png")

printf '%-11s %5s %6s %6s %7s %6s %11s %11s %11s %7s %6s %11s %8s %8s\n' floor "m/s" frames "fix %" off-map losses \
  "fix max mm" "truth cam" "revisit" places fails "truth veh" "NIS<95%" "NIS mean"
for floor in $FLOORS; do
  texture=${TEXTURE[$floor]}
  [ "$texture" = procedural ] || [ -f "$texture" ] || { echo "$floor: $texture is absent, skipped"; continue; }
  dir="$WORK/$floor"
  mkdir -p "$dir"
  if [ ! -f "$dir/map.mosaic" ]; then
    printf 'route: {name: network, network_scale: 1.0, speed_mps: 0.5, max_accel_mps2: 1.0}\nrun: {laps: 1, seed: 81}\n' \
      > "$dir/map.yaml"
    "$MOSAICLOC" -q simulate --out "$dir/mapping" --overwrite --config "$dir/map.yaml" --floor "$texture" >/dev/null
    "$MOSAICLOC" -q map build --dataset "$dir/mapping" --out "$dir/map.mosaic" --overwrite >/dev/null
  fi
  for speed in 1.5 7.2; do
    drive="$dir/d$speed"
    if [ ! -d "$drive" ]; then
      printf 'route: {name: network, network_scale: 1.0, speed_mps: %s, max_accel_mps2: 3.0}\nrun: {laps: 2, seed: 84}\n' \
        "$speed" > "$dir/d$speed.yaml"
      printf 'encoders: {left_radius_error: 0.02, right_radius_error: 0.025}\n' >> "$dir/d$speed.yaml"
      "$MOSAICLOC" -q simulate --out "$drive" --overwrite --config "$dir/d$speed.yaml" --floor "$texture" >/dev/null
    fi
    # The same recording without its ground truth.
    rm -rf "$drive-blind"
    mkdir -p "$drive-blind"
    ln -s "$drive/cam0" "$drive-blind/cam0"
    ln -s "$drive/encoders" "$drive-blind/encoders"
    cp "$drive/dataset.yaml" "$drive-blind/"
    rm -rf "$drive-truth-report" "$drive-blind-report"
    "$MOSAICLOC" -q replay --dataset "$drive-blind" --map "$dir/map.mosaic" --out "$drive-blind-report" >/dev/null
    # The visual fixes as a trajectory, aligned rigidly to the truth: that alignment is where
    # the map's frame lies in the truth's. The truth-based figures are taken in the map's frame
    # (a self-built map is turned by a few hundredths of a degree; at the camera that turn
    # times the spread of a place's visits is micrometres, which no registration can see).
    "$PYTHON" -c '
import sys
out = open(sys.argv[2], "w")
for line in open(sys.argv[1]):
    f = line.split(",")
    if line.startswith("#") or f[6] != "1":
        continue
    print("%.9f %.7f %.7f 0 0 0 0 1" % (int(f[0]) / 1e9, float(f[1]) / 1000, float(f[2]) / 1000), file=out)
' "$drive-blind-report/fixes.csv" "$drive-blind-report/fixes.tum"
    aligned=$("$PYTHON" "$HERE/benchmarks/aligned.py" "$drive-blind-report/fixes.tum" "$drive/groundtruth/data.tum" \
      --placement)
    "$MOSAICLOC" -q replay --dataset "$drive" --map "$dir/map.mosaic" --out "$drive-truth-report" \
      --truth-from-map="$(echo "$aligned" | cut -d' ' -f3)" --revisit-places 0 >/dev/null
    "$PYTHON" - "$drive-truth-report/metrics.json" "$drive-blind-report/metrics.json" "$floor" "$speed" "$aligned" <<'PY'
import json, sys
t, b = (json.load(open(f)) for f in sys.argv[1:3])
f = lambda v, fmt: "n/a" if v is None else fmt % v
print("%-11s %5s %6d %6.1f %7s %6d %11s %11s %11s %7s %6s %11s %8s %8s" % (
    sys.argv[3], sys.argv[4], b["frames"], 100 * b["fix_rate"], b["frames_by_state"].get("off-map", 0),
    b["lock_losses"], "%.4f" % float(sys.argv[5].split()[1]), f(t["repeatability_camera_mm"], "%.5f"),
    f(b["revisit_repeatability_mm"], "%.5f"), f(b["revisit_places"], "%d"), f(b["revisit_failures"], "%d"),
    f(t["repeatability_mm"], "%.5f"), f(None if b["nis_inside_95_share"] is None else 100 * b["nis_inside_95_share"], "%.1f"),
    f(b["nis_mean"], "%.3f")))
PY
  done
done
