# A vehicle that leaves the mapped lanes over a repeating floor (design.md section 7): a
# network of lanes mapped in one lap at 1 m/s, then driven for two laps at 2 m/s with wheels 2 %
# and 2.5 % larger than calibrated; the second lap takes lanes the first did not, so the view
# leaves the map for a second or more at a time. The floor repeats (asphalt every 512 mm,
# brick every 256 mm), so off the lanes the view matches copies of the floor on mapped lanes
# one period away. No fix may be wrong: off the map the localizer dead-reckons and says so,
# and back on it the first fix is on the truth within three frames.
# Usage: excursion.sh MOSAICLOC TEXTURE
source "$(dirname "$0")/lib.sh"
FLOOR="${MOSAICLOC_SHARED_DATA:-}/textures/$2"
if [ ! -f "$FLOOR" ]; then
  echo "shared data folder with real textures not found (MOSAICLOC_SHARED_DATA=${MOSAICLOC_SHARED_DATA:-unset}): skipped"
  exit 77
fi
printf 'route: {network_scale: 0.5}\n' > "$SCRATCH/map.yaml"
printf 'route: {network_scale: 0.5}\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\n' \
  > "$SCRATCH/drive.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/map" --floor "$FLOOR" --route network --laps 1 \
  --speed-mps 1.0 --seed 81 --config "$SCRATCH/map.yaml"
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/map" --out "$SCRATCH/floor.mosaic" --poses groundtruth
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/drive" --floor "$FLOOR" --route network --laps 2 \
  --speed-mps 2.0 --seed 82 --config "$SCRATCH/drive.yaml"
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/floor.mosaic" \
  --out "$SCRATCH/report" --revisit-places 0
python3 - "$SCRATCH/report" "$SCRATCH/drive/groundtruth/data.tum" "$2" <<'PY' || fail "$2: excursion"
import bisect, json, math, sys
report, truth_file, name = sys.argv[1:4]
m = json.load(open(report + "/metrics.json"))
print(name, {k: m[k] for k in ("fix_rate", "lock_losses", "wrong_fixes", "max_wrong_fix_mm", "off_map_frames",
                               "off_map_max_error_mm", "reentries", "reentry_frames_to_fix_max",
                               "reentry_first_fix_error_max_mm")})
assert m["wrong_fixes"] == 0 and m["max_wrong_fix_mm"] == 0, m
assert m["lock_losses"] == 0, m
assert m["off_map_frames"] >= 100 and m["reentries"] >= 3, m
assert m["reentry_frames_to_fix_max"] <= 3 and m["reentry_first_fix_error_max_mm"] <= 0.05, m
# The report's own count, checked here from fixes.csv against the truth: every visual fix
# within 1 mm, every off-map row a dead-reckoned estimate with status 4.
truth = []
for line in open(truth_file):
    if not line.startswith("#") and line.strip():
        t, x, y = (float(v) for v in line.split()[:3])
        truth.append((round(t * 1e9), x * 1000.0, y * 1000.0))
times = [t for t, _, _ in truth]
worst, off_map, modes = 0.0, 0, {}
for line in open(report + "/fixes.csv"):
    if line.startswith("#"):
        continue
    ns, x, y, _, status, quality, fixed, _, _, _, reason, mode = line.rstrip("\n").split(",")
    if status == "4":
        off_map += 1
        assert fixed == "0" and quality == "0" and reason == "off-map", line
        assert mode in ("visual-odometry", "dead-reckoning"), line
        modes[mode] = modes.get(mode, 0) + 1
    if fixed != "1":
        continue
    ns, x, y = int(ns), float(x), float(y)
    i = min(max(bisect.bisect_left(times, ns), 1), len(truth) - 1)
    (t0, x0, y0), (t1, x1, y1) = truth[i - 1], truth[i]
    a = (ns - t0) / (t1 - t0)
    worst = max(worst, math.hypot(x - (x0 + a * (x1 - x0)), y - (y0 + a * (y1 - y0))))
assert worst <= 1.0, worst
assert off_map == m["off_map_frames"], (off_map, m["off_map_frames"])
# Off the map the frames are registered frame to keyframe and chained: visual odometry.
print(name, "off the map:", modes, "mode switches", m["mode_switches"], m["frames_by_mode"])
assert modes.get("visual-odometry", 0) >= 0.5 * off_map, modes
assert m["frames_by_mode"].get("visual-odometry", 0) == modes.get("visual-odometry", 0), m["frames_by_mode"]
PY
# The map's self-test knows the floor repeats. A vehicle carried unseen while its estimate is
# put 400 mm aside, off the lanes, confidently: it drives on by visual odometry, its estimate
# comes back onto the map where the view does not match, and the lock is lost. A place found
# then near the failed prediction may be a copy of the floor (one period from the truth), so
# it is checked against the whole map, where the floor's copies make it ambiguous: no wrong fix.
# (Without that check, 879 fixes one period, 512 mm, off on asphalt, from 12.5 s on.)
expect_exit 0 "$MOSAICLOC" map info "$SCRATCH/floor.mosaic"
expect_in "$SCRATCH/out" "floor: repeats"
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/floor.mosaic" \
  --out "$SCRATCH/carried" --revisit-places 0 --kidnap-at-s 5 --kidnap-offset 0,-400,0 --until-s 20
python3 - "$SCRATCH/carried/metrics.json" "$2" <<'PY' || fail "$2: carried unseen"
import json, sys
m = json.load(open(sys.argv[1]))
print(sys.argv[2], "carried unseen:", {k: m[k] for k in ("fix_rate", "lock_losses", "wrong_fixes", "max_wrong_fix_mm",
                                                       "kidnap_frames_to_fix")})
assert m["wrong_fixes"] == 0 and m["max_wrong_fix_mm"] == 0, m
PY
finish
