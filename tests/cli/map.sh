# map build / info / check / export as a user runs them, damage on disk, and a build killed
# half way.
source "$(dirname "$0")/lib.sh"
printf 'camera: {width_px: 320, height_px: 240}\nroute: {speed_mps: 1.0}\nrun: {frames: 90}\n' > "$SCRATCH/c.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/ds" --config "$SCRATCH/c.yaml"

expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/a.mosaic" --tile-size 128
expect_in "$SCRATCH/out" "90 frames painted"
expect_exit 2 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/ds" --out "$SCRATCH/a.mosaic"
expect_in "$SCRATCH/err" "already exists"
expect_exit 0 "$MOSAICLOC" --json map info "$SCRATCH/a.mosaic"
expect_in "$SCRATCH/out" '"tile_size_px": 128'
expect_in "$SCRATCH/out" '"extent_mm"'
expect_exit 0 "$MOSAICLOC" map check "$SCRATCH/a.mosaic"
expect_in "$SCRATCH/out" "tiles intact"
expect_exit 0 "$MOSAICLOC" --quiet map export "$SCRATCH/a.mosaic" --out "$SCRATCH/a.png" --level 1
[ -s "$SCRATCH/a.png" ] || fail "no export written"
expect_exit 0 "$MOSAICLOC" map export "$SCRATCH/a.mosaic" --out "$SCRATCH/r.png" --region 0,-50,100,50
expect_in "$SCRATCH/out" "400 x 400 px"
expect_exit 2 "$MOSAICLOC" map export "$SCRATCH/a.mosaic" --out "$SCRATCH/r.png" --region 0,50,100
expect_in "$SCRATCH/err" "--region must be x0,y0,x1,y1"

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
expect_exit 2 "$MOSAICLOC" map info "$SCRATCH/missing.mosaic"
expect_in "$SCRATCH/err" "no such map file"
finish
