# The integrator's console in a real browser (Debian's chromium, headless):
#  - `serve` over a self-built map with a replay report and the map's mapping report: the API,
#    the page's tiles (in the DOM and in a screenshot's pixels), both reports' layers;
#  - what it refuses: paths outside its files, writes, another interface without the flag and
#    a token, a request without the token;
# (console_live.sh: the console inside `run`.)
source "$(dirname "$0")/lib.sh"
command -v chromium >/dev/null || { fail "chromium is not installed (scripts/install-deps.sh installs it)"; finish; }
[ -f /usr/share/javascript/leaflet/leaflet.js ] || { fail "libjs-leaflet is not installed (scripts/install-deps.sh)"; finish; }

# A 2 m straight of procedural floor, mapped from its frames and encoders (with the mapping
# report), and a drive over it replayed.
printf 'route: {straight_length_m: 2.0, stop_s: 0.7}\n' > "$SCRATCH/site.yaml"
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/site-map" --config "$SCRATCH/site.yaml" --floor procedural \
  --route straight --laps 1 --speed-mps 0.5 --seed 31 >/dev/null || fail "simulate the mapping drive"
"$MOSAICLOC" --quiet map build --dataset "$SCRATCH/site-map" --out "$SCRATCH/site.mosaic" \
  --report "$SCRATCH/mapping" >/dev/null || fail "map build"
[ -s "$SCRATCH/mapping/path.csv" ] || fail "the mapping report has no path.csv"
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/site-run" --config "$SCRATCH/site.yaml" --floor procedural \
  --route straight --laps 1 --speed-mps 1.0 --seed 32 >/dev/null || fail "simulate the drive"
"$MOSAICLOC" --quiet replay --dataset "$SCRATCH/site-run" --map "$SCRATCH/site.mosaic" --out "$SCRATCH/replay" \
  --revisit-places 0 >/dev/null || fail "replay"

# The map's quality layer, computed by map build: procedural floor has texture everywhere and
# no copies.
expect_exit 0 "$MOSAICLOC" --json map quality "$SCRATCH/site.mosaic" --out "$SCRATCH/quality"
json_check "$SCRATCH/out" 'd["judged"] >= 10' 'd["weak_cells"] == 0' 'd["computed_s"] is None'
[ -s "$SCRATCH/quality/quality.png" ] && head -1 "$SCRATCH/quality/weak.csv" | grep -q "^#stretch,cells" \
  || fail "map quality did not write quality.png and weak.csv"

# --- serve -----------------------------------------------------------------------------------
PORT=$(free_port)
"$MOSAICLOC" serve --map "$SCRATCH/site.mosaic" --report "$SCRATCH/replay" --report "$SCRATCH/mapping" \
  --listen "127.0.0.1:$PORT" >"$SCRATCH/serve.out" 2>"$SCRATCH/serve.err" &
SERVE=$!
wait_port "$PORT"
URL="http://127.0.0.1:$PORT"
expect_in "$SCRATCH/serve.out" "console: $URL/"
curl -sf "$URL/api/map" > "$SCRATCH/map.json" || fail "GET /api/map"
curl -sf "$URL/api/quality" > "$SCRATCH/quality.json" || fail "GET /api/quality"
json_check "$SCRATCH/quality.json" 'd["available"] is True' 'd["cell_mm"] == 128' \
  'sum(1 for c in d["cells"] if c[5] == 0) >= 10' 'all(c[5] not in (1, 2) for c in d["cells"])'
json_check "$SCRATCH/map.json" 'd["mm_per_px"] == 0.25' 'd["levels"][0]["tiles"] > 0' 'd["bounds_mm"][2] > 1900' \
  'd["place_index"] is not None' 'd["live_run"] is False'
curl -sf "$URL/api/reports" > "$SCRATCH/reports.json" || fail "GET /api/reports"
$PYTHON - "$SCRATCH/reports.json" <<'PY' || fail "the reports"
import json, sys
r = json.load(open(sys.argv[1]))
assert [x["kind"] for x in r] == ["replay", "mapping"], r
PY
curl -sf "$URL/api/reports/0" > "$SCRATCH/replay.json" || fail "GET /api/reports/0"
json_check "$SCRATCH/replay.json" 'd["columns"][6:] == ["error_mm", "mode"]' 'set(p[7] for p in d["points"]) == {"track"}' \
  'max(p[6] for p in d["points"] if p[6] is not None) < 1.0' 'len(d["points"]) == d["frames"]'
curl -sf "$URL/api/reports/1" > "$SCRATCH/mapping.json" || fail "GET /api/reports/1"
json_check "$SCRATCH/mapping.json" 'len(d["points"]) > 50' 'd["metrics"]["frames"] > 50'
# A tile comes as the map stores it (a PNG); unmapped ones and anything else are 404.
TILE=$($PYTHON -c 'import json,math,sys; d=json.load(open(sys.argv[1])); t=d["tile_size_px"]*d["mm_per_px"]
print(math.floor((1000 - d["origin_x_mm"]) / t), math.floor((d["origin_y_mm"] - 0) / t), sep="/")' "$SCRATCH/map.json")
code=$(curl -s -o "$SCRATCH/tile.png" -w '%{http_code}' "$URL/api/tiles/0/$TILE.png")
[ "$code" = 200 ] && head -c 8 "$SCRATCH/tile.png" | grep -q PNG || fail "tile 0/$TILE (under x 1 m, y 0): HTTP $code"
for path in "/api/tiles/0/99999/99999.png" "/leaflet/../../../../etc/passwd" "/..%2f..%2f..%2fetc%2fpasswd" \
            "/api/reports/0/../../../etc/passwd" "/site.mosaic"; do
  code=$(curl -s --path-as-is -o "$SCRATCH/body" -w '%{http_code}' "$URL$path")
  [ "$code" = 404 ] || [ "$code" = 400 ] || fail "$path: HTTP $code"
  grep -q "root:" "$SCRATCH/body" && fail "$path served a system file"
done
code=$(curl -s -o /dev/null -w '%{http_code}' -X POST -d '{}' "$URL/api/map")
[ "$code" = 405 ] || fail "POST: HTTP $code (the console is read-only)"

# The page: tiles load and draw, both reports' layers appear.
browse "$URL/#1000,0,-1" "$SCRATCH/serve.png" > "$SCRATCH/dom.html"
dom_check "$SCRATCH/dom.html" 'data.get("ready") == "yes"' 'int(data.get("tiles-loaded", 0)) >= 2' \
  'data.get("reports") == "2"' 'int(data.get("quality-cells", 0)) >= 10' 'dom.count("report-state") >= 1' 'dom.count("report-seams") >= 1' \
  're.search(r"<p id=\"error\"[^>]*></p>", dom)'
# The screenshot's map area shows the floor's grey texture, not only the black background.
$PYTHON - "$SCRATCH/serve.png" <<'PY' || fail "the mosaic does not show in the screenshot"
import struct, sys, zlib
png = open(sys.argv[1], "rb").read()
assert png[:8] == b"\x89PNG\r\n\x1a\n"
pos, idat, header = 8, b"", None
while pos < len(png):
    length, kind = struct.unpack(">I4s", png[pos:pos + 8])
    chunk = png[pos + 8:pos + 8 + length]
    if kind == b"IHDR":
        header = struct.unpack(">IIBBBBB", chunk)
    elif kind == b"IDAT":
        idat += chunk
    pos += 12 + length
width, height, depth, colour = header[:4]
assert depth == 8 and colour in (2, 6), header
bpp = 3 if colour == 2 else 4
raw = zlib.decompress(idat)
stride = width * bpp
rows, prev, i = [], bytearray(stride), 0
for _ in range(height):
    kind, line = raw[i], bytearray(raw[i + 1:i + 1 + stride])
    i += 1 + stride
    for x in range(stride):
        a = line[x - bpp] if x >= bpp else 0
        b = prev[x]
        c = prev[x - bpp] if x >= bpp else 0
        if kind == 1: line[x] = (line[x] + a) & 255
        elif kind == 2: line[x] = (line[x] + b) & 255
        elif kind == 3: line[x] = (line[x] + (a + b) // 2) & 255
        elif kind == 4:
            p = a + b - c
            pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
    rows.append(line)
    prev = line
# The map is the left 600 px (the panel is 300 px wide): grey pixels of the floor there.
grey = sum(1 for y in range(0, height, 2) for x in range(0, width - 300, 2)
           if 25 < rows[y][x * bpp] < 235 and abs(rows[y][x * bpp] - rows[y][x * bpp + 1]) < 6
           and abs(rows[y][x * bpp + 1] - rows[y][x * bpp + 2]) < 6)
share = grey / ((height // 2) * ((width - 300) // 2))
print(f"floor texture in {share:.1%} of the map area")
assert share > 0.05, share
PY

# The map written while it is served: a drive half a metre past the mapped straight maps the
# new floor (automatic mapping, a recorded update); the console reads the map anew and the
# page draws the update's tiles; after `map revert` the update shows as reverted.
printf 'route: {straight_length_m: 2.5, stop_s: 0.7}\n' > "$SCRATCH/longer.yaml"
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/longer" --config "$SCRATCH/longer.yaml" --floor procedural \
  --route straight --laps 1 --speed-mps 1.0 --seed 33 >/dev/null || fail "simulate the longer drive"
"$MOSAICLOC" --quiet replay --dataset "$SCRATCH/longer" --map "$SCRATCH/site.mosaic" --mapping \
  --out "$SCRATCH/longer-report" --revisit-places 0 >/dev/null || fail "replay --mapping"
sleep 0.6
curl -sf "$URL/api/history" > "$SCRATCH/history.json" || fail "GET /api/history"
json_check "$SCRATCH/history.json" 'd["count"] == 1' 'd["in_force"] == 1' 'd["updates"][0]["kind"] == "mapping"' \
  'len(d["updates"][0]["cells"]) == d["updates"][0]["tiles"] > 0' \
  "d['map_version'] > $($PYTHON -c 'import json,sys; print(json.load(open(sys.argv[1]))["map_version"])' "$SCRATCH/map.json")"
curl -sf "$URL/api/map" > "$SCRATCH/map2.json" || fail "GET /api/map after mapping"
json_check "$SCRATCH/map2.json" 'd["bounds_mm"][2] > 2300'
browse "$URL/#2300,0,-1" > "$SCRATCH/dom2.html"
dom_check "$SCRATCH/dom2.html" 'data.get("ready") == "yes"' 'data.get("history-updates") == "1"' \
  'dom.count("history-mapping") >= 1' 're.search(r"id=\"map-history\">1 update, 1 in force", dom)'
expect_exit 0 "$MOSAICLOC" --quiet map revert "$SCRATCH/site.mosaic" 1
sleep 0.6
curl -sf "$URL/api/history" > "$SCRATCH/history.json" || fail "GET /api/history after the revert"
json_check "$SCRATCH/history.json" 'd["in_force"] == 0' 'd["updates"][0]["reverted"] is not None'
kill -INT $SERVE
wait $SERVE || fail "serve did not stop cleanly on SIGINT"
expect_in "$SCRATCH/serve.out" "console stopped"

# Refused: another interface without --allow-remote, with it but no token; a request without
# the token when one is set.
expect_exit 2 "$MOSAICLOC" serve --map "$SCRATCH/site.mosaic" --listen "0.0.0.0:$PORT" --duration 1
expect_in "$SCRATCH/err" "allow_remote"
expect_exit 2 "$MOSAICLOC" serve --map "$SCRATCH/site.mosaic" --listen "0.0.0.0:$PORT" --allow-remote --duration 1
expect_in "$SCRATCH/err" "token"
echo "console-token-for-this-test-0001" > "$SCRATCH/token"
"$MOSAICLOC" serve --map "$SCRATCH/site.mosaic" --listen "127.0.0.1:$PORT" --token-file "$SCRATCH/token" \
  --duration 20 >"$SCRATCH/serve.out" 2>/dev/null &
SERVE=$!
wait_port "$PORT"
code=$(curl -s -o /dev/null -w '%{http_code}' "$URL/api/map")
[ "$code" = 401 ] || fail "no token: HTTP $code"
code=$(curl -s -o /dev/null -w '%{http_code}' -H "Authorization: Bearer console-token-for-this-test-0001" "$URL/api/map")
[ "$code" = 200 ] || fail "with the token: HTTP $code"
browse "$URL/?token=console-token-for-this-test-0001" > "$SCRATCH/dom.html"
dom_check "$SCRATCH/dom.html" 'int(data.get("tiles-loaded", 0)) >= 1'
kill -INT $SERVE; wait $SERVE

finish
