# Automatic mapping (design.md section 7d) on the procedural floor: a lap of a small network of
# lanes driven from an empty map maps it as it goes (visual odometry off the map, stretches
# closed onto the floor already mapped), and a faster lap then tracks the map it made. A
# mapping replay killed with SIGKILL leaves a map that checks clean and holds every stretch
# it said it had committed, and mapping goes on from it.
# Usage: automatic_mapping.sh MOSAICLOC
source "$(dirname "$0")/lib.sh"
# json_check FILE EXPR...: every Python expression holds for the JSON object d read from FILE.
json_check() {
  local file=$1
  shift
  python3 - "$file" "$@" <<'PY' || fail "$file: $*"
import json, sys
d = json.load(open(sys.argv[1]))
print(sys.argv[1], {k: v for k, v in d.items() if k.startswith("map_extension") or k in ("fix_rate", "lock_losses", "wrong_fixes", "max_wrong_fix_mm", "repeatability_camera_mm", "frames_by_mode")})
for check in sys.argv[2:]:
    assert eval(check), check
PY
}
printf 'route: {network_scale: 0.2}\n' > "$SCRATCH/site.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/lap" --floor procedural --route network --laps 1 \
  --speed-mps 1.0 --seed 61 --config "$SCRATCH/site.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/drive" --floor procedural --route network --laps 1 \
  --speed-mps 2.0 --seed 62 --config "$SCRATCH/site.yaml"

# A map that does not exist needs --mapping to be made.
expect_exit 2 "$MOSAICLOC" replay --dataset "$SCRATCH/lap" --map "$SCRATCH/site.mosaic" --out "$SCRATCH/r0"
expect_in "$SCRATCH/err" "give --mapping to create it"

expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/lap" --map "$SCRATCH/site.mosaic" --mapping \
  --out "$SCRATCH/mapped" --revisit-places 0
[ -f "$SCRATCH/mapped/mapped.tum" ] && [ -f "$SCRATCH/mapped/map_mode.png" ] || fail "mapped.tum or map_mode.png missing"
json_check "$SCRATCH/mapped/metrics.json" 'd["map_extension_keyframes"] > 100' 'd["map_extension_closed"] >= 1' \
  'd["map_extension_unanchored"] <= d["frames"] // 50' 'd["map_extension_pose_max_mm"] < 5.0' \
  'd["frames_by_mode"]["visual-odometry"] > d["frames"] // 2' 'd["lock_losses"] == 0' \
  'd["map_extension_overspeed_frames"] == 0' '0.9 < d["map_extension_speed_max_mps"] < d["overlap_speed_limit_mps"]'
expect_exit 0 "$MOSAICLOC" --quiet map check "$SCRATCH/site.mosaic"
# The map it made has a place index and a quality layer over the new floor, as map build's has.
expect_exit 0 "$MOSAICLOC" --quiet --json map info "$SCRATCH/site.mosaic"
json_check "$SCRATCH/out" 'd["place_index"]["features"] > 1000' 'd["quality"]["cells"] > 50'

# The floor was mapped by visual odometry: its own poses lie up to map_extension_pose_max_mm
# (about 1 mm) off the truth, and a fix that agrees with the map is that far off too. A fix on
# it is wrong when it lies further from the truth than the map itself does (plus 0.5 mm).
BOUND=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['map_extension_pose_max_mm'] + 0.5)" \
  "$SCRATCH/mapped/metrics.json")

# The next lap, twice as fast, tracks the map the first one made.
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/site.mosaic" \
  --out "$SCRATCH/tracked" --revisit-places 0
json_check "$SCRATCH/tracked/metrics.json" 'd["fix_rate"] >= 0.97' 'd["lock_losses"] == 0' "d['max_wrong_fix_mm'] < $BOUND" \
  'd["repeatability_camera_mm"] <= 0.01' 'd["frames_by_mode"]["track"] >= 0.97 * d["frames"]'

# The map's self-test (made with its place index when the mapping ended): the procedural floor
# does not repeat. So a vehicle carried unseen to where its estimate lies off the map (400 mm
# aside, held there confidently) searches the whole map from off it and finds itself again
# within lock.off_map_global_every (10) frames, without a wrong fix (with that search off: 47
# frames and a lost lock, until its estimate drifted back onto the map).
expect_exit 0 "$MOSAICLOC" map info "$SCRATCH/site.mosaic"
expect_in "$SCRATCH/out" "floor: does not repeat"
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/site.mosaic" \
  --out "$SCRATCH/carried" --revisit-places 0 --kidnap-at-s 5 --kidnap-offset 0,-400,0
json_check "$SCRATCH/carried/metrics.json" "d['max_wrong_fix_mm'] < $BOUND" 'd["kidnap_frames_to_fix"] <= 12' \
  'd["off_map_frames"] <= 12'
# Carried 1.5 m back along its lane: the view half matches where the estimate puts it, which
# on this floor without copies is evidence of the move; the search without the prior finds it.
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/site.mosaic" \
  --out "$SCRATCH/carried_back" --revisit-places 0 --kidnap-at-s 5 --kidnap-offset -1500,0,0
json_check "$SCRATCH/carried_back/metrics.json" "d['max_wrong_fix_mm'] < $BOUND" 'd["kidnap_frames_to_fix"] <= 8' \
  'd["lock_losses"] == 0'

# Mapping faster than the overlap speed limit (2.4 m/s along the view's long side at 30 Hz) is
# warned of, once for the episode, and counted.
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/fast" --floor procedural --route straight --frames 150 \
  --speed-mps 3.0 --seed 64
expect_exit 0 "$MOSAICLOC" --json replay --dataset "$SCRATCH/fast" --map "$SCRATCH/fast.mosaic" --mapping \
  --out "$SCRATCH/fast_report" --revisit-places 0
[ "$(grep -c 'above the overlap speed limit' "$SCRATCH/err")" -eq 1 ] || fail "no single overspeed warning"
json_check "$SCRATCH/fast_report/metrics.json" 'd["map_extension_overspeed_frames"] >= 30' \
  'd["map_extension_speed_max_mps"] > d["overlap_speed_limit_mps"]'

# Killed while mapping in stretches of 0.3 m: every stretch it logged as committed is in the map.
printf 'map_extension: {max_segment_m: 0.3}\n' > "$SCRATCH/short.yaml"
"$MOSAICLOC" replay --dataset "$SCRATCH/lap" --map "$SCRATCH/killed.mosaic" --mapping --out "$SCRATCH/killed" \
  --revisit-places 0 --config "$SCRATCH/short.yaml" > "$SCRATCH/killed.log" 2>&1 &
pid=$!
for _ in $(seq 1 600); do
  [ "$(grep -c 'map extension: committed' "$SCRATCH/killed.log")" -ge 3 ] && break
  sleep 0.02
done
kill -9 "$pid" 2>/dev/null
wait "$pid" 2>/dev/null
committed=$(grep -o 'holds [0-9]* tiles' "$SCRATCH/killed.log" | tail -1 | tr -dc '0-9')
[ -n "$committed" ] || fail "no stretch committed before the kill"
expect_exit 0 "$MOSAICLOC" --quiet map check "$SCRATCH/killed.mosaic"
expect_exit 0 "$MOSAICLOC" --quiet --json map info "$SCRATCH/killed.mosaic"
json_check "$SCRATCH/out" "d['levels'][0]['tiles'] >= $committed"
# Mapping goes on from what the killed run left.
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/lap" --map "$SCRATCH/killed.mosaic" --mapping \
  --out "$SCRATCH/resumed" --revisit-places 0
json_check "$SCRATCH/resumed/metrics.json" 'd["lock_losses"] == 0' 'd["wrong_fixes"] == 0 or d["map_extension_pose_max_mm"] < 5.0'
expect_exit 0 "$MOSAICLOC" --quiet map check "$SCRATCH/killed.mosaic"
finish
