#!/usr/bin/env bash
# Global relocalization on the 85 m network route (design.md section 7b): for each floor, a map
# painted at the true poses of one lap at 0.5 m/s (wheels 2 % / 2.5 % off) and indexed, then
#   - `locate` on every EVERY-th frame of a later drive at 1.5 m/s (other noise): found,
#     ambiguous, no match, within 0.05 mm of the truth, wrong (over 1 mm), ms p50/p99;
#   - replays of that drive starting without a pose, and kidnapped 20 s in (the estimate moved
#     10 m aside unseen, told as by the PLC's request, and 3 m back along the lane, not told).
# Usage: relocalization_table.sh [MOSAICLOC] [WORK] [FLOORS] [EVERY]
#   FLOORS: any of "procedural asphalt asphalt-patches brick" (those but procedural need
#   ../shared/data). asphalt is the picture tiled, a floor that repeats every 512 mm;
#   asphalt-patches is a floor of the same material that never repeats (floor.image_layout).
#   A floor name ending in -changed (procedural-changed, asphalt-patches-changed) drives over
#   that floor changed since it was mapped: grime over 20 %, stains and tyre marks.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
MOSAICLOC="${1:-$HERE/../build/dev/app/mosaicloc}"
WORK="${2:-/tmp/mosaicloc-relocalization}"
FLOORS="${3:-procedural asphalt brick}"
EVERY="${4:-2}"
SHARED="${MOSAICLOC_SHARED_DATA:-$HERE/../../shared/data}"
mkdir -p "$WORK"
floor_args() {
  case "$1" in
    procedural*) echo "--floor procedural" ;;
    asphalt*) echo "--floor $SHARED/textures/asphalt_02_2048.jpg" ;;
    brick*) echo "--floor $SHARED/textures/brick_floor_1024.png" ;;
  esac
}
# The mapping lap and the later drive of FLOOR into DIR/map.yaml and DIR/drive.yaml.
write_configs() {
  local layout=repeat changes="{}"
  case "$1" in *-patches*) layout=patches ;; esac
  case "$1" in *-changed) changes="{seed: 3, grime_fraction: 0.2, grime_strength: 0.3, stains_per_m2: 0.3, tyre_marks: 0.15}" ;; esac
  printf 'route: {name: network, network_scale: 1.0, speed_mps: 0.5, max_accel_mps2: 1.0}\nrun: {laps: 1, seed: 81}\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\nfloor: {image_layout: %s}\n' \
    "$layout" >"$2/map.yaml"
  printf 'route: {name: network, network_scale: 1.0, speed_mps: 1.5, max_accel_mps2: 1.0}\nrun: {laps: 1, seed: 82}\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\nfloor: {image_layout: %s}\nchanges: %s\n' \
    "$layout" "$changes" >"$2/drive.yaml"
}
echo "| floor | frames | found | ambiguous | no match | within 0.05 mm | wrong | ms p50 | ms p99 | index features | index MiB |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
for floor in $FLOORS; do
  dir="$WORK/$floor"
  mkdir -p "$dir"
  write_configs "$floor" "$dir"
  # A changed floor is located on the map of the floor as it was.
  base="$WORK/${floor%-changed}"
  if [ "$base" != "$dir" ] && [ -f "$base/truth.mosaic" ] && [ ! -f "$dir/truth.mosaic" ]; then
    cp "$base/truth.mosaic" "$dir/truth.mosaic"
  fi
  # shellcheck disable=SC2046
  [ -d "$dir/map" ] || [ -f "$dir/truth.mosaic" ] || "$MOSAICLOC" --quiet simulate --out "$dir/map" $(floor_args "$floor") --config "$dir/map.yaml" >/dev/null
  # shellcheck disable=SC2046
  [ -d "$dir/drive" ] || "$MOSAICLOC" --quiet simulate --out "$dir/drive" $(floor_args "$floor") --config "$dir/drive.yaml" >/dev/null
  [ -f "$dir/truth.mosaic" ] || "$MOSAICLOC" --quiet map build --dataset "$dir/map" --out "$dir/truth.mosaic" --poses groundtruth >/dev/null
  "$MOSAICLOC" --quiet --json locate --map "$dir/truth.mosaic" --dataset "$dir/drive" --every "$EVERY" >"$dir/locate.json"
  /usr/bin/python3 - "$dir/locate.json" "$floor" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
print(f"| {sys.argv[2]} | {d['frames']} | {d['found']} | {d['ambiguous']} | {d['no_match']} | {d.get('within_0_05_mm', '-')} | "
      f"{d.get('wrong', '-')} | {d['ms_p50']:.1f} | {d['ms_p99']:.1f} | {d['index_features']} | {d['index_memory_bytes'] / 2**20:.1f} |")
PY
done
echo
echo "| floor | replay | fix rate | lock losses | wrong | relocalizations | frames to first fix | kidnap: frames to fix |"
echo "|---|---|---|---|---|---|---|---|"
for floor in $FLOORS; do
  dir="$WORK/$floor"
  run() {
    local name=$1; shift
    "$MOSAICLOC" --quiet --json replay --dataset "$dir/drive" --map "$dir/truth.mosaic" --out "$dir/replay-$name" "$@" >/dev/null
    /usr/bin/python3 - "$dir/replay-$name/metrics.json" "$floor" "$name" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
f = lambda k: "-" if m.get(k) is None else m[k]
print(f"| {sys.argv[2]} | {sys.argv[3]} | {100 * m['fix_rate']:.2f} % | {f('lock_losses')} | {f('wrong_fixes')} | "
      f"{f('relocalizations')} | {f('frames_to_first_fix')} | {f('kidnap_frames_to_fix')} |")
PY
  }
  run unknown-start --unknown-start
  run kidnap-10m-told --kidnap-at-s 20 --kidnap-offset 10000,3000,30 --kidnap-told
  run kidnap-3m-back --kidnap-at-s 20 --kidnap-offset -3000,0,0
done
