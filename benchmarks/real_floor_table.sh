#!/usr/bin/env bash
# The real-floor tables: a vehicle whose camera changes height and tilts, and a floor that
# changed since it was mapped, on procedural concrete and the real textures of
# ../shared/data. Every drive has wheels 2 % and 2.5 % larger than calibrated; every row
# counts wrong fixes (more than 1 mm from the truth).
#  geometry: for each case, a loop mapped at its true poses at 0.5 m/s on the same floor by a
#    vehicle that does not pitch (flat: as simulated by default; offset+4, drift: the camera
#    4 mm higher, or drifting 10 mm/min, on the drive only; uneven1/2: the floor 1 or 2 mm RMS
#    in waves of 2 to 4 m; susp: the body pitching 0.3 and rolling 0.2 deg per m/s^2 about an
#    axis 100 mm over the floor; susp0: about the floor; both: uneven1 and susp; k1: residual
#    distortion 0.002), driven at 1.5 m/s, replayed with the default tracker and with the tilt
#    estimated (twelve templates; pivot 100 mm for offset/susp/both, 0 for the rest). Columns:
#    the height the localizer held against the truth (h rms), and the RMS of the image
#    centre's offset from the mounting point the tilt caused (lever).
#  fast: the same cases on a 20 m straight driven at 7.2 m/s (3 m/s^2).
#  changes: a loop mapped on the clean floor, driven over the floor changed since (grime,
#    stains, tyre marks, a wet patch, a replaced tile 300 mm square, lane lines, all);
#    fix_out is the fix rate of the frames whose view is clear of the tile.
#  share: how much of the view may change before fixes stop: drives over a replaced tile and
#    across painted bands of growing size; each frame's share of the view over the change.
#  MAP_POSES=estimated paints the geometry and fast tables' maps at the poses `map build`
#    estimates from the mapping drive's frames and encoders instead of at the true poses (a
#    self-built map, checked in its own frame: on an uneven floor its own shape's error, about
#    0.2 mm for the uneven cases, then shows in every fix); MAP_POSES=estimated-flat the same
#    with `map build --flat-floor` (each frame taken at the calibrated height, straight down:
#    about 1 mm off on the uneven cases).
# Usage: [CASES="flat susp ..."] [MAP_POSES=groundtruth|estimated|estimated-flat] benchmarks/real_floor_table.sh [MOSAICLOC] [WORK_DIR] [TABLES] [FLOORS]
#        TABLES: any of "geometry fast changes share" (default all); FLOORS: any of
#        "procedural asphalt brick" (default all three; the textures need ../shared/data)
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
TABLES=${3:-geometry fast changes share}
FLOORS=${4:-procedural asphalt brick}
source "$HERE/benchmarks/table_lib.sh"
case ${MAP_POSES:=groundtruth} in
  groundtruth) MAP_POSES_ARGS=(--poses groundtruth) ;;
  estimated) MAP_POSES_ARGS=() ;;
  estimated-flat) MAP_POSES_ARGS=(--flat-floor) ;;
  *) echo "MAP_POSES must be groundtruth, estimated or estimated-flat, got '$MAP_POSES'" >&2; exit 2 ;;
esac
WHEELS='encoders: {left_radius_error: 0.02, right_radius_error: 0.025}'
mkdir -p "$WORK"
sed 's/estimate_tilt: false/estimate_tilt: true/; s/  count: 4 /  count: 12 /' "$HERE/config/default/localizer.yaml" \
  > "$WORK/tilt0.yaml"
sed 's/tilt_pivot_height_mm: 0.0 /tilt_pivot_height_mm: 100.0 /' "$WORK/tilt0.yaml" > "$WORK/tilt100.yaml"
grep -q "count: 12 " "$WORK/tilt0.yaml" && grep -q "tilt_pivot_height_mm: 100.0 " "$WORK/tilt100.yaml"

# The replay's figures in one row; $1 case, $2 case directory, $3 report directory.
row() {
  "$PYTHON" - "$@" <<'PY'
import csv, json, math, sys
case, d, rep = sys.argv[1:4]
m = json.load(open(rep + "/metrics.json"))
cam = {int(r[0]): r for r in csv.reader(open(d + "/drive/groundtruth/camera.csv")) if not r[0].startswith("#")}
lever = [math.hypot(float(r[4]), float(r[5])) for r in cam.values()]
g = lambda k, f: (f % m[k]) if m.get(k) is not None else "n/a"
print(f"{case:<15} {g('fix_rate','%9.4f')} {g('lock_losses','%6d')} {g('wrong_fixes','%6d')} {g('position_rms_mm','%8.4f')} "
      f"{g('position_max_mm','%8.4f')} {g('height_error_rms_mm','%8.4f')} {math.sqrt(sum(e*e for e in lever)/len(lever)):8.4f} "
      f"{g('processing_fps','%7.0f')}")
PY
}

declare -A CASE=(
  [flat]='{}'
  [offset+4]='camera: {height_offset_mm: 4.0}'
  [drift]='camera: {height_drift_mm_per_min: 10.0}'
  [uneven1]='floor: {unevenness_mm: 1.0, unevenness_wavelength_m: 2.0}'
  [uneven2]='floor: {unevenness_mm: 2.0, unevenness_wavelength_m: 2.0}'
  [susp]='suspension: {pitch_deg_per_mps2: 0.3, roll_deg_per_mps2: 0.2, pivot_height_mm: 100}'
  [susp0]='suspension: {pitch_deg_per_mps2: 0.3, roll_deg_per_mps2: 0.2, pivot_height_mm: 0}'
  [both]=$'floor: {unevenness_mm: 1.0, unevenness_wavelength_m: 2.0}\nsuspension: {pitch_deg_per_mps2: 0.3, roll_deg_per_mps2: 0.2, pivot_height_mm: 100}'
  [k1]='camera: {residual_k1: 0.002}'
)
# geometry_table TAG ROUTE SPEED EXTRA: every case on one floor ($floor, $name).
geometry_table() {
  local tag=$1 route=$2 speed=$3 extra=$4
  printf '%-15s %9s %6s %6s %8s %8s %8s %8s %7s   (%s %s, %s m/s, map at %s poses)\n' case fix_rate losses wrong rms_mm max_mm \
    h_rms lever fps "$name" "$route" "$speed" "$MAP_POSES"
  for c in ${CASES:-flat offset+4 drift uneven1 uneven2 susp susp0 both k1}; do
    local d="$WORK/$tag-$name/$c"
    mkdir -p "$d"
    # The map: the drive's floor, from a vehicle that does not pitch, at the calibrated height.
    case $c in
      offset+4|drift|susp|susp0) echo '{}' > "$d/map.yaml" ;;
      both) printf '%s\n' "${CASE[uneven1]}" > "$d/map.yaml" ;;
      *) printf '%s\n' "${CASE[$c]}" > "$d/map.yaml" ;;
    esac
    printf '%s\n%s\n%s\n' "${CASE[$c]}" "$WHEELS" "$extra" > "$d/drive.yaml"
    local map="$d/map-$MAP_POSES.mosaic"
    [ -d "$d/map" ] || "$MOSAICLOC" -q simulate --out "$d/map" --overwrite --floor "$floor" --route "$route" \
        --laps 1 --speed-mps 0.5 --seed 21 --config "$d/map.yaml" >/dev/null
    local reporting=()
    [ "$MAP_POSES" != groundtruth ] && reporting=(--report "$d/map-report-$MAP_POSES")
    [ -f "$map" ] || "$MOSAICLOC" -q map build --dataset "$d/map" --out "$map" --overwrite "${MAP_POSES_ARGS[@]}" \
      "${reporting[@]}" >/dev/null
    # A self-built map has a frame of its own: the truth is checked in it (the mapping report's
    # best rigid alignment), so the fixes' errors are the localization's and the map's shape's.
    local placement=()
    if [ "$MAP_POSES" != groundtruth ]; then
      placement=("--truth-from-map=$("$PYTHON" -c 'import json,sys; t=json.load(open(sys.argv[1]))["vs_groundtruth"]["truth_from_map"]; print("%.9f,%.9f,%.12f" % (t["x_mm"], t["y_mm"], t["yaw_deg"]))' "$d/map-report-$MAP_POSES/consistency.json")")
    fi
    [ -d "$d/drive" ] || "$MOSAICLOC" -q simulate --out "$d/drive" --floor "$floor" --route "$route" --laps 1 \
      --speed-mps "$speed" --seed 22 --config "$d/drive.yaml" >/dev/null
    for tracker in default tilt; do
      local config=()
      if [ $tracker = tilt ]; then
        case $c in offset+4|susp|both) config=(--config "$WORK/tilt100.yaml") ;; *) config=(--config "$WORK/tilt0.yaml") ;; esac
      fi
      local report="$d/$tracker-$MAP_POSES"
      rm -rf "${report:?}"
      "$MOSAICLOC" -q replay --dataset "$d/drive" --map "$map" --out "$report" "${config[@]}" "${placement[@]}" >/dev/null 2>&1 || true
      row "$c $tracker" "$d" "$report"
    done
  done
}

for name in $FLOORS; do
  floor=$(floor_path "$name")
  if [ "$floor" != procedural ] && [ ! -f "$floor" ]; then echo "$name: no texture at $floor, skipped"; continue; fi
  if [[ " $TABLES " == *" geometry "* ]]; then geometry_table loop loop 1.5 ''; fi
  if [[ " $TABLES " == *" fast "* ]]; then geometry_table fast straight 7.2 'route: {max_accel_mps2: 3.0}'; fi
done

CHANGES=(
  "none|{}"
  "grime40|changes: {grime_fraction: 0.4, grime_strength: 0.5}"
  "grime80x|changes: {grime_fraction: 0.8, grime_strength: 1.0}"
  "stains20|changes: {stains_per_m2: 20}"
  "tyre|changes: {tyre_marks: 0.6, tyre_track_width_mm: 100}"
  "wet|changes: {wet_patch: {x_mm: 1500, y_mm: 0, radius_mm: 300, strength: 1.0}}"
  "tile300|changes: {replaced_tile: {x_mm: 1500, y_mm: 2000, size_mm: 300}}"
  "lane_across|changes: {lane_line: {x0_mm: 1000, y0_mm: -400, x1_mm: 1000, y1_mm: 400, width_mm: 100}}"
  "lane_along|changes: {lane_line: {x0_mm: 500, y0_mm: 40, x1_mm: 3000, y1_mm: 40, width_mm: 50}}"
  "all|changes: {grime_fraction: 0.4, grime_strength: 0.5, stains_per_m2: 5, tyre_marks: 0.6, tyre_track_width_mm: 100, wet_patch: {x_mm: 1500, y_mm: 0, radius_mm: 300}, replaced_tile: {x_mm: 1500, y_mm: 2000, size_mm: 300}, lane_line: {x0_mm: 1000, y0_mm: -400, x1_mm: 1000, y1_mm: 400, width_mm: 100}}"
)
for name in $FLOORS; do
  [[ " $TABLES " == *" changes "* || " $TABLES " == *" share "* ]] || break
  floor=$(floor_path "$name")
  if [ "$floor" != procedural ] && [ ! -f "$floor" ]; then continue; fi
  base="$WORK/changes-$name"
  mkdir -p "$base"
  [ -f "$base/map.mosaic" ] || { "$MOSAICLOC" -q simulate --out "$base/map" --overwrite --floor "$floor" --route loop --laps 1 \
      --speed-mps 0.5 --seed 21 >/dev/null
    "$MOSAICLOC" -q map build --dataset "$base/map" --out "$base/map.mosaic" --overwrite >/dev/null; }
  drive() {  # drive DIR CHANGES: the loop at 1.5 m/s over the changed floor, replayed
    mkdir -p "$1"
    printf '%s\n%s\n' "$2" "$WHEELS" > "$1/drive.yaml"
    [ -d "$1/drive" ] || "$MOSAICLOC" -q simulate --out "$1/drive" --floor "$floor" --route loop --laps 1 --speed-mps 1.5 \
      --seed 22 --config "$1/drive.yaml" >/dev/null
    rm -rf "${1:?}/rep"
    "$MOSAICLOC" -q replay --dataset "$1/drive" --map "$base/map.mosaic" --out "$1/rep" >/dev/null 2>&1 || true
  }
  if [[ " $TABLES " == *" changes "* ]]; then
    printf '%-11s %9s %9s %6s %6s %8s %8s %9s   (%s, loop 1.5 m/s)\n' case fix_rate fix_out losses wrong rms_mm max_mm max_wrong "$name"
    for entry in "${CHANGES[@]}"; do
      c=${entry%%|*}
      drive "$base/$c" "${entry#*|}"
      "$PYTHON" - "$c" "$base/$c" <<'PY'
import csv, json, math, sys
c, d = sys.argv[1:3]
m = json.load(open(d + "/rep/metrics.json"))
near = set()
for l in open(d + "/drive/groundtruth/data.tum"):
    if l.startswith("#"): continue
    p = l.split(); yaw = 2 * math.atan2(float(p[6]), float(p[7]))
    x, y = float(p[1]) * 1e3 + 200 * math.cos(yaw), float(p[2]) * 1e3 + 200 * math.sin(yaw)
    if abs(x - 1500) < 250 and abs(y - 2000) < 250: near.add(round(float(p[0]) * 1e9))
rows = [r for r in csv.reader(open(d + "/rep/fixes.csv")) if not r[0].startswith("#")]
out = [r for r in rows if int(r[0]) not in near]
g = lambda k, f: (f % m[k]) if m.get(k) is not None else "n/a"
print(f"{c:<11} {g('fix_rate','%9.4f')} {sum(r[6] == '1' for r in out) / len(out):9.4f} {g('lock_losses','%6d')} "
      f"{g('wrong_fixes','%6d')} {g('position_rms_mm','%8.4f')} {g('position_max_mm','%8.4f')} {g('max_wrong_fix_mm','%9.3f')}")
PY
    done
  fi
  if [[ " $TABLES " == *" share "* ]]; then
    for a in 80 120 160 240 320; do
      drive "$base/share-tile-$a" "changes: {replaced_tile: {x_mm: 1500, y_mm: 0, size_mm: $a}}"
      drive "$base/share-lane-$a" "changes: {lane_line: {x0_mm: 1500, y0_mm: -400, x1_mm: 1500, y1_mm: 400, width_mm: $a}}"
    done
    "$PYTHON" - "$base" "$name" <<'PY'
import collections, csv, glob, math, sys
base, name = sys.argv[1:3]
bins = collections.defaultdict(lambda: [0, 0, 0])
for d in sorted(glob.glob(base + "/share-*")):
    kind, a = d.split("share-")[1].split("-")[0], float(d.rsplit("-", 1)[1])
    truth = {}
    for l in open(d + "/drive/groundtruth/data.tum"):
        if l.startswith("#"): continue
        p = l.split(); yaw = 2 * math.atan2(float(p[6]), float(p[7])); x, y = float(p[1]) * 1e3, float(p[2]) * 1e3
        truth[round(float(p[0]) * 1e9)] = (x + 200 * math.cos(yaw), y + 200 * math.sin(yaw), x, y)
    x0, x1 = 1500 - a / 2, 1500 + a / 2
    y0, y1 = (-a / 2, a / 2) if kind == "tile" else (-400, 400)
    for r in csv.reader(open(d + "/rep/fixes.csv")):
        if r[0].startswith("#") or int(r[0]) not in truth: continue
        cx, cy, vx, vy = truth[int(r[0])]
        if abs(cy) > 100 or not 800 < cx < 2200: continue  # the bottom straight, near the change
        share = max(0, min(cx + 80, x1) - max(cx - 80, x0)) * max(0, min(cy + 60, y1) - max(cy - 60, y0)) / (160 * 120)
        b = min(int(share * 5), 4) if share > 0 else -1
        s = bins[(kind, b)]; s[0] += 1; s[1] += r[6] == "1"
        s[2] += r[6] == "1" and math.hypot(float(r[1]) - vx, float(r[2]) - vy) > 1.0
print(f"change  share of the view   frames  fix rate  wrong   ({name})")
for (kind, b), (n, f, w) in sorted(bins.items()):
    label = "0 (near it)" if b < 0 else f"{20 * b}-{20 * b + 20} %"
    print(f"{kind:<7} {label:<19} {n:6d}  {f / n:8.3f}  {w:5d}")
PY
  fi
done
