# map build / info / check / export as a user runs them, damage on disk, a build killed
# half way, and builds resumed after an interruption.
source "$(dirname "$0")/lib.sh"
printf 'camera: {width_px: 320, height_px: 240}\nroute: {speed_mps: 1.0}\nrun: {frames: 90}\n' > "$SCRATCH/c.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/ds" --config "$SCRATCH/c.yaml"

expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/a.mosaic" --tile-size 128
expect_in "$SCRATCH/out" "90 frames painted"
expect_exit 2 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/a.mosaic"
expect_in "$SCRATCH/err" "already exists"
# A consistency report exists only for estimated poses: asked for with the truth's, it is refused
# (nothing written), not silently left out.
expect_exit 2 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/gt.mosaic" --poses groundtruth \
  --report "$SCRATCH/gt-report"
expect_in "$SCRATCH/err" "--report: the consistency report is the estimated poses'"
[ ! -e "$SCRATCH/gt.mosaic" ] && [ ! -e "$SCRATCH/gt-report" ] || fail "a refused map build wrote something"
expect_exit 0 "$MOSAICLOC" --json map info "$SCRATCH/a.mosaic"
expect_in "$SCRATCH/out" '"tile_size_px": 128'
expect_in "$SCRATCH/out" '"extent_mm"'
expect_exit 0 "$MOSAICLOC" map check "$SCRATCH/a.mosaic"
expect_in "$SCRATCH/out" "tiles intact"
# The place index: built with the map, shown by info, used by locate and by a replay that does
# not know where it starts; every frame found where the ground truth says, none wrong.
expect_exit 0 "$MOSAICLOC" map info "$SCRATCH/a.mosaic"
expect_in "$SCRATCH/out" "place index:"
expect_exit 0 "$MOSAICLOC" --quiet locate --map "$SCRATCH/a.mosaic" --dataset "$SCRATCH/ds" --every 30
expect_in "$SCRATCH/out" "3 frames: 3 found (100.0 %)"
expect_in "$SCRATCH/out" "3 of 3 within 0.05 mm, 0 wrong"
first=$(ls "$SCRATCH/ds/cam0/data" | sort -n | head -1)
expect_exit 0 "$MOSAICLOC" --json locate --map "$SCRATCH/a.mosaic" "$SCRATCH/ds/cam0/data/$first"
expect_in "$SCRATCH/out" '"outcome": "found"'
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/ds" --map "$SCRATCH/a.mosaic" --out "$SCRATCH/unknown" --unknown-start
expect_in "$SCRATCH/unknown/metrics.json" '"wrong_fixes": 0'
expect_in "$SCRATCH/unknown/metrics.json" '"relocalizations": 1'
expect_in "$SCRATCH/unknown/metrics.json" '"frames_to_first_fix": 0'
# A map made before the index existed: it still opens; locate says how to index it, and map
# index does.
cp "$SCRATCH/a.mosaic" "$SCRATCH/old.mosaic"
python3 - "$SCRATCH/old.mosaic" <<'PY'
import sqlite3, sys
db = sqlite3.connect(sys.argv[1])
db.execute("DROP TABLE places")
db.execute("DELETE FROM metadata WHERE name LIKE 'places_%'")
db.commit()
PY
expect_exit 0 "$MOSAICLOC" map info "$SCRATCH/old.mosaic"
expect_in "$SCRATCH/out" "place index: none (global relocalization needs one: mosaicloc map index"
expect_exit 2 "$MOSAICLOC" --quiet locate --map "$SCRATCH/old.mosaic" "$SCRATCH/ds/cam0/data/$first"
expect_in "$SCRATCH/err" "has no place index: build it with \`mosaicloc map index"
expect_exit 0 "$MOSAICLOC" --quiet map index "$SCRATCH/old.mosaic"
expect_in "$SCRATCH/out" "place index of"
expect_exit 0 "$MOSAICLOC" --quiet locate --map "$SCRATCH/old.mosaic" "$SCRATCH/ds/cam0/data/$first"
# A damaged cell of the index: map check names it.
python3 - "$SCRATCH/old.mosaic" <<'PY'
import sqlite3, sys
db = sqlite3.connect(sys.argv[1])
db.execute("UPDATE places SET data = substr(data, 1, 10) || X'0102' || substr(data, 13) WHERE rowid = (SELECT MIN(rowid) FROM places)")
db.commit()
PY
expect_exit 2 "$MOSAICLOC" map check "$SCRATCH/old.mosaic"
expect_in "$SCRATCH/err" "place index cell"
expect_exit 0 "$MOSAICLOC" --quiet map export "$SCRATCH/a.mosaic" --out "$SCRATCH/a.png" --level 1
[ -s "$SCRATCH/a.png" ] || fail "no export written"
expect_exit 0 "$MOSAICLOC" map export "$SCRATCH/a.mosaic" --out "$SCRATCH/r.png" --region 0,-50,100,50
expect_in "$SCRATCH/out" "400 x 400 px"
expect_exit 2 "$MOSAICLOC" map export "$SCRATCH/a.mosaic" --out "$SCRATCH/r.png" --region 0,50,100
expect_in "$SCRATCH/err" "region must be x0,y0,x1,y1"

# A tile damaged on disk: check names it and exits 2; export still works around it.
cp "$SCRATCH/a.mosaic" "$SCRATCH/b.mosaic"
python3 - "$SCRATCH/b.mosaic" <<'PY'
import sqlite3, sys
db = sqlite3.connect(sys.argv[1])
level, col, row = db.execute("SELECT level, col, row FROM tiles WHERE level = 0 ORDER BY row, col LIMIT 1").fetchone()
db.execute("UPDATE tiles SET data = substr(data, 1, 60) || X'00FF00FF' || substr(data, 65) WHERE level=? AND col=? AND row=?", (level, col, row))
db.commit()
print(f"level {level} col {col} row {row}")
PY
damaged=$(python3 -c "import sqlite3,sys; print('level %d col %d row %d' % sqlite3.connect(sys.argv[1]).execute('SELECT level, col, row FROM tiles WHERE level = 0 ORDER BY row, col LIMIT 1').fetchone())" "$SCRATCH/b.mosaic")
expect_exit 2 "$MOSAICLOC" map check "$SCRATCH/b.mosaic"
expect_in "$SCRATCH/err" "tile $damaged: CRC32 mismatch"
expect_exit 0 "$MOSAICLOC" --quiet map export "$SCRATCH/b.mosaic" --out "$SCRATCH/b.png" --level 0

# Killed while building: the previous map is untouched, and no half map is left in its place.
cp "$SCRATCH/a.mosaic" "$SCRATCH/c.mosaic"
before=$(md5sum < "$SCRATCH/c.mosaic")
"$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/c.mosaic" --overwrite --tile-size 32 \
  >/dev/null 2>&1 &
pid=$!
sleep 0.7
kill -9 $pid 2>/dev/null
wait $pid 2>/dev/null
after=$(md5sum < "$SCRATCH/c.mosaic")
if [ "$before" != "$after" ]; then
  # The build finished before the kill: then the new map must be whole.
  expect_exit 0 "$MOSAICLOC" map check "$SCRATCH/c.mosaic"
  echo "note: the build finished before it was killed"
fi
expect_exit 0 "$MOSAICLOC" map check "$SCRATCH/c.mosaic"

# Resumable builds. same_map A B: the two maps hold the same tiles, byte for byte.
same_map() {
  python3 - "$1" "$2" <<'PY' || fail "$1 and $2 differ"
import sqlite3, sys
def tiles(path):
    db = sqlite3.connect(path)
    rows = db.execute("SELECT level, col, row, crc32, length(data) FROM tiles ORDER BY level, col, row").fetchall()
    meta = db.execute("SELECT name, value FROM metadata ORDER BY name").fetchall()
    return rows, meta
a, b = tiles(sys.argv[1]), tiles(sys.argv[2])
if a != b:
    print(f"{len(a[0])} against {len(b[0])} tiles", file=sys.stderr)
    sys.exit(1)
PY
}
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/ref.mosaic" --tile-size 64
[ -e "$SCRATCH/ref.mosaic.checkpoint" ] && fail "a finished build left its checkpoint"
[ -e "$SCRATCH/ref.mosaic.poses.tum" ] && fail "a finished build left its estimated poses"

# The poses alone, the pose graph out and back in (g2o), and a damaged graph named by line.
# The drive is straight: nothing bounds its drift, and it says so.
expect_exit 0 "$MOSAICLOC" map poses --dataset "$SCRATCH/ds" --out "$SCRATCH/p.tum" --graph-out "$SCRATCH/g.g2o" \
  --report "$SCRATCH/consistency"
expect_in "$SCRATCH/out" "warning: the drive never came back"
expect_in "$SCRATCH/out" "against the ground truth"
# Its 1.5 m show too little floor for the camera's flat field: mapped as they are, and said.
expect_in "$SCRATCH/out" "warning: the drive shows too little floor for the camera's flat field"
[ "$(grep -vc '^#' "$SCRATCH/p.tum")" -eq 90 ] || fail "p.tum does not hold the 90 frames' poses"
for f in consistency.json loops.csv seams.csv residuals.png; do [ -s "$SCRATCH/consistency/$f" ] || fail "no $f"; done
# The map built from those poses has a frame of its own; a replay checked in it (the report's
# best rigid alignment onto the truth) measures the localization, not the map's placement.
placement=$(python3 -c "import json,sys; t=json.load(open(sys.argv[1]))['vs_groundtruth']['truth_from_map']; \
print('%r,%r,%r' % (t['x_mm'], t['y_mm'], t['yaw_deg']))" "$SCRATCH/consistency/consistency.json")
expect_exit 0 "$MOSAICLOC" --quiet replay --dataset "$SCRATCH/ds" --map "$SCRATCH/ref.mosaic" --out "$SCRATCH/in-world"
expect_exit 0 "$MOSAICLOC" --quiet replay --dataset "$SCRATCH/ds" --map "$SCRATCH/ref.mosaic" --out "$SCRATCH/in-map" \
  --truth-from-map="$placement"
python3 -c "import json,sys; a, b = (json.load(open(f))['position_rms_mm'] for f in sys.argv[1:]); \
sys.exit(0 if a < b else 1)" "$SCRATCH/in-map/metrics.json" "$SCRATCH/in-world/metrics.json" ||
  fail "the replay checked in the map's frame is no closer to the truth than in the world's"
expect_exit 2 "$MOSAICLOC" --quiet replay --dataset "$SCRATCH/ds" --map "$SCRATCH/ref.mosaic" --out "$SCRATCH/x" \
  --truth-from-map=1,2
expect_in "$SCRATCH/err" "truth-from-map"
grep -q '^VERTEX_SE2 89 ' "$SCRATCH/g.g2o" || fail "the graph lacks node 89"
expect_exit 0 "$MOSAICLOC" --quiet map poses --dataset "$SCRATCH/ds" --graph-in "$SCRATCH/g.g2o" --out "$SCRATCH/q.tum"
sed '5s/.*/EDGE_SE2 0 1 0.01 zero 0 1 0 0 1 0 1/' "$SCRATCH/g.g2o" > "$SCRATCH/bad.g2o"
expect_exit 2 "$MOSAICLOC" --quiet map poses --dataset "$SCRATCH/ds" --graph-in "$SCRATCH/bad.g2o" --out "$SCRATCH/b.tum"
expect_in "$SCRATCH/err" "bad.g2o:5: 'zero' is not a finite number"
[ -e "$SCRATCH/b.tum" ] && fail "a rejected graph left a trajectory"

# A second drive over the same floor (other noise, another path within the lane), started
# where its dataset says to within 4 mm (the 80 mm x 60 mm view must cover the search),
# mapped with the first into one map: loop closures join it; each drive's poses are written.
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/ds3" --config "$SCRATCH/c.yaml" --seed 7
expect_exit 0 "$MOSAICLOC" --json map poses --dataset "$SCRATCH/ds" --join "$SCRATCH/ds3" --join-sigma-mm 4 \
  --out "$SCRATCH/j.tum"
loops=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['loops_accepted'])" "$SCRATCH/out")
[ "$loops" -gt 0 ] || fail "no loop closure joined the second drive"
[ "$(grep -vc '^#' "$SCRATCH/j.2.tum")" -eq 90 ] || fail "j.2.tum does not hold the second drive's 90 poses"
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --join "$SCRATCH/ds3" --out "$SCRATCH/j.mosaic" \
  --tile-size 64 --join-sigma-mm 4
expect_in "$SCRATCH/out" "180 frames painted"
[ -e "$SCRATCH/j.mosaic.poses.2.tum" ] && fail "a finished build left the second drive's estimated poses"
expect_exit 2 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --join "$SCRATCH/ds3" --out "$SCRATCH/x.mosaic" \
  --poses "$SCRATCH/p.tum"
expect_in "$SCRATCH/err" "a TUM file holds one drive's poses"

# Stopped by a damaged frame half way through painting (at the ground truth's poses: with
# estimated ones the mapping stops at it first): no map, a checkpoint (which is not a map); the
# frame repaired, --resume continues after the frames already painted and gives the same map.
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/gt.mosaic" --tile-size 64 \
  --poses groundtruth
cp -r "$SCRATCH/ds" "$SCRATCH/ds2"
frame=$(sed -n '47p' "$SCRATCH/ds2/cam0/data.csv" | cut -d, -f2)
cp "$SCRATCH/ds2/cam0/data/$frame" "$SCRATCH/frame.png"
head -c 100 "$SCRATCH/frame.png" > "$SCRATCH/ds2/cam0/data/$frame"
expect_exit 2 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds2" --out "$SCRATCH/e.mosaic" --tile-size 64
expect_in "$SCRATCH/err" "cannot be decoded"
[ -e "$SCRATCH/e.mosaic" ] && fail "a mapping stopped by a damaged frame left a map"
expect_exit 2 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds2" --out "$SCRATCH/r.mosaic" --tile-size 64 \
  --checkpoint-s 0 --poses groundtruth
expect_in "$SCRATCH/err" "cannot be decoded"
[ -e "$SCRATCH/r.mosaic" ] && fail "an interrupted build left a map"
[ -s "$SCRATCH/r.mosaic.checkpoint" ] || fail "an interrupted build left no checkpoint"
expect_exit 2 "$MOSAICLOC" map info "$SCRATCH/r.mosaic.checkpoint"
cp "$SCRATCH/frame.png" "$SCRATCH/ds2/cam0/data/$frame"
expect_exit 2 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds2" --out "$SCRATCH/r.mosaic" --tile-size 64 \
  --resume --blend best-view --poses groundtruth
expect_in "$SCRATCH/err" "made by a build with blend 'feather', not 'best-view'"
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds2" --out "$SCRATCH/r.mosaic" --tile-size 64 --resume \
  --poses groundtruth
expect_in "$SCRATCH/out" "90 frames painted"
expect_in "$SCRATCH/out" "resumed after 45 of 90 frames"
same_map "$SCRATCH/gt.mosaic" "$SCRATCH/r.mosaic"
[ -e "$SCRATCH/r.mosaic.checkpoint" ] && fail "a resumed build left its checkpoint"

# kill -9 part way through painting at the estimated poses (once 20 frames are saved), then
# --resume: the resumed build paints at the poses the killed one estimated.
killed_at=$(python3 - "$MOSAICLOC" "$SCRATCH" <<'PY'
import signal, sqlite3, subprocess, sys, time
program, scratch = sys.argv[1:3]
out = scratch + "/k.mosaic"
build = subprocess.Popen([program, "--quiet", "map", "build", "--dataset", scratch + "/ds", "--out", out,
                          "--tile-size", "64", "--checkpoint-s", "0"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
done, deadline = 0, time.time() + 30
while build.poll() is None and time.time() < deadline:
    try:
        db = sqlite3.connect("file:" + out + ".checkpoint?mode=ro", uri=True, timeout=0.05)
        row = db.execute("SELECT value FROM build WHERE name = 'frames_done'").fetchone()
        db.close()
        done = int(row[0]) if row else 0
    except sqlite3.Error:
        pass
    if done >= 20:
        build.send_signal(signal.SIGKILL)
        break
    time.sleep(0.002)
build.wait()
print(done if build.returncode == -signal.SIGKILL else -1)
PY
)
if [ "$killed_at" -ge 0 ]; then
  [ -e "$SCRATCH/k.mosaic" ] && fail "a killed build left a map"
  expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/k.mosaic" --tile-size 64 --resume
  resumed=$(sed -n 's/.*resumed after \([0-9]*\) of 90 frames.*/\1/p' "$SCRATCH/out")
  if [ "$killed_at" -lt 90 ] && [ "${resumed:-0}" -lt "$killed_at" ]; then
    fail "killed after $killed_at frames were saved, resumed after ${resumed:-0}"
  fi
else
  echo "note: the build finished before it could be killed"
fi
same_map "$SCRATCH/ref.mosaic" "$SCRATCH/k.mosaic"
expect_exit 0 "$MOSAICLOC" map check "$SCRATCH/k.mosaic"

expect_exit 2 "$MOSAICLOC" map info "$SCRATCH/missing.mosaic"
expect_in "$SCRATCH/err" "no such map file"
finish
