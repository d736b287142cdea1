# Automatic map updates (design.md section 7e) on the procedural floor: a small loop mapped, then
# driven three times over a floor where a 60 mm tile was replaced since. The second pass rewrites
# it, from frames whose pose is right to 0.05 mm, in updates the map's history keeps: `map
# history` lists them and `map revert` undoes them. A kidnapped vehicle writes nothing from a
# pose that is off, and a replay killed with SIGKILL after an update leaves a map that checks
# clean and holds it.
# Usage: map_updates.sh MOSAICLOC
source "$(dirname "$0")/lib.sh"
# json_check FILE EXPR...: every Python expression holds for the JSON object d read from FILE.
json_check() {
  local file=$1
  shift
  python3 - "$file" "$@" <<'PY' || fail "$file: $*"
import json, sys
d = json.load(open(sys.argv[1]))
print(sys.argv[1], {k: v for k, v in d.items() if k.startswith("map_update") or k in ("fix_rate", "lock_losses", "wrong_fixes", "updates", "updates_in_force")})
for check in sys.argv[2:]:
    assert eval(check), check
PY
}
# near_quality FIXES X Y: the mean fix quality (per mille) of each pass of the camera within 60 mm
# of (X, Y) mm, then the median quality of the fixes farther than 200 mm from it (the floor that
# did not change), one line.
near_quality() {
  python3 - "$@" <<'PY'
import csv, math, sys
path, x0, y0 = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
passes, last, away = [], None, []
for row in csv.DictReader(l for l in open(path) if not l.startswith('#') or l.startswith('#timestamp')):
    t = int(row['#timestamp_ns']) * 1e-9
    x, y, yaw = float(row['x_mm']), float(row['y_mm']), float(row['yaw_rad'])
    d = math.hypot(x + 200 * math.cos(yaw) - x0, y + 200 * math.sin(yaw) - y0)
    if d > 200 and row['status'] == '1': away.append(float(row['quality']))
    if d > 60: continue
    if last is None or t - last > 2.0: passes.append([])
    last = t
    passes[-1].append(float(row['quality'] or 0))
print(' '.join('%.1f' % (sum(p) / len(p)) for p in passes), sorted(away)[len(away) // 2])
PY
}
printf 'route: {loop_width_m: 2.0, loop_height_m: 1.2}\n' > "$SCRATCH/site.yaml"
cat "$SCRATCH/site.yaml" - > "$SCRATCH/changed.yaml" <<'YAML'
changes: {replaced_tile: {x_mm: 700.0, y_mm: 0.0, size_mm: 60.0}}
YAML
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/lap" --floor procedural --route loop --laps 1 \
  --speed-mps 1.0 --seed 71 --config "$SCRATCH/site.yaml"
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/lap" --out "$SCRATCH/site.mosaic" --poses groundtruth
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/changed" --floor procedural --route loop --laps 3 \
  --speed-mps 1.5 --seed 72 --config "$SCRATCH/changed.yaml"

# The changed tile is rewritten on the second pass, from a pose right to 0.05 mm, and the fix
# quality over it on the third pass is that of the unchanged floor.
cp "$SCRATCH/site.mosaic" "$SCRATCH/updated.mosaic"
expect_exit 0 "$MOSAICLOC" --quiet replay --dataset "$SCRATCH/changed" --map "$SCRATCH/updated.mosaic" --mapping \
  --out "$SCRATCH/r_updated" --revisit-places 0
json_check "$SCRATCH/r_updated/metrics.json" 'd["map_updates"] >= 1' 'd["map_update_cells"] >= 4' \
  'd["map_update_pose_max_mm"] < 0.05' 'd["wrong_fixes"] == 0' 'd["lock_losses"] == 0' 'd["fix_rate"] >= 0.99'
quality=$(near_quality "$SCRATCH/r_updated/fixes.csv" 700 0)
echo "fix quality near the replaced tile, per pass, and the median elsewhere: $quality"
python3 -c "
*passes, elsewhere = [float(v) for v in '$quality'.split()]
assert len(passes) == 3, passes
assert passes[0] < elsewhere - 10, 'the first pass sees the change'
assert passes[2] >= 0.995 * elsewhere, 'the third pass sees the floor as mapped'
" || fail "fix quality near the replaced tile: $quality"

# The history lists the updates; reverting them, newest first, gives back the map as it was.
expect_exit 0 "$MOSAICLOC" --quiet map history "$SCRATCH/updated.mosaic"
expect_in "$SCRATCH/out" "seen changed on 2 passes"
expect_exit 0 "$MOSAICLOC" --quiet --json map info "$SCRATCH/updated.mosaic"
json_check "$SCRATCH/out" 'd["updates"] >= 1' 'd["updates_in_force"] == d["updates"]'
updates=$(python3 -c "import json; print(json.load(open('$SCRATCH/out'))['updates'])")
for id in $(seq "$updates" -1 1); do
  expect_exit 0 "$MOSAICLOC" --quiet map revert "$SCRATCH/updated.mosaic" "$id"
  expect_in "$SCRATCH/out" "update $id reverted"
done
expect_exit 2 "$MOSAICLOC" --quiet map revert "$SCRATCH/updated.mosaic" 1
expect_in "$SCRATCH/err" "already reverted"
expect_exit 2 "$MOSAICLOC" --quiet map revert "$SCRATCH/updated.mosaic" 99
expect_in "$SCRATCH/err" "update 99: no such update"
expect_exit 0 "$MOSAICLOC" --quiet map check "$SCRATCH/updated.mosaic"
expect_exit 0 "$MOSAICLOC" --quiet map export "$SCRATCH/updated.mosaic" --out "$SCRATCH/reverted.png" --level 0
expect_exit 0 "$MOSAICLOC" --quiet map export "$SCRATCH/site.mosaic" --out "$SCRATCH/original.png" --level 0
cmp -s "$SCRATCH/reverted.png" "$SCRATCH/original.png" || fail "the reverted map differs from the original"

# A vehicle kidnapped 40 mm sideways before its second pass: whatever it sees until it is found
# again, nothing is written from a pose that is off.
cp "$SCRATCH/site.mosaic" "$SCRATCH/kidnap.mosaic"
expect_exit 0 "$MOSAICLOC" --quiet replay --dataset "$SCRATCH/changed" --map "$SCRATCH/kidnap.mosaic" --mapping \
  --out "$SCRATCH/r_kidnap" --revisit-places 0 --kidnap-at-s 4 --kidnap-offset 0,40,0
json_check "$SCRATCH/r_kidnap/metrics.json" 'd["map_update_pose_max_mm"] is None or d["map_update_pose_max_mm"] < 0.05' \
  'd["wrong_fixes"] == 0'

# Killed with SIGKILL after its first update: the map checks clean and holds it.
cp "$SCRATCH/site.mosaic" "$SCRATCH/killed.mosaic"
"$MOSAICLOC" replay --dataset "$SCRATCH/changed" --map "$SCRATCH/killed.mosaic" --mapping --out "$SCRATCH/r_killed" \
  --revisit-places 0 > "$SCRATCH/killed.log" 2>&1 &
pid=$!
for _ in $(seq 1 1000); do
  grep -q '(update 1)' "$SCRATCH/killed.log" && break
  sleep 0.01
done
kill -9 "$pid" 2>/dev/null
wait "$pid" 2>/dev/null
grep -q '(update 1)' "$SCRATCH/killed.log" || fail "no update before the kill: $(tail -c 600 "$SCRATCH/killed.log")"
expect_exit 0 "$MOSAICLOC" --quiet map check "$SCRATCH/killed.mosaic"
expect_exit 0 "$MOSAICLOC" --quiet --json map info "$SCRATCH/killed.mosaic"
json_check "$SCRATCH/out" 'd["updates"] >= 1'
finish
