# Commissioning a site with the console (quoted line for line by README.md; CI runs it).
printf 'route: {straight_length_m: 2.0, stop_s: 0.7}\n' > site.yaml
mosaicloc --quiet simulate --out mapping-drive --config site.yaml --floor procedural --route straight --laps 1 --speed-mps 0.5 --seed 1
mosaicloc --quiet map build --dataset mapping-drive --out site.mosaic --report mapping-report
mosaicloc --quiet simulate --out drive --config site.yaml --floor procedural --route straight --laps 1 --speed-mps 1.5 --seed 2
mosaicloc --quiet replay --dataset drive --map site.mosaic --out drive-report --revisit-places 0
mosaicloc --quiet map quality site.mosaic --out quality
mosaicloc serve --map site.mosaic --report drive-report --report mapping-report --listen 127.0.0.1:0 > console.txt &
SERVE=$!
until grep -q "^console: http" console.txt; do sleep 0.1; done
URL=$(sed -n 's/^console: \(http[^ ]*\) .*/\1/p' console.txt)
curl -s "${URL}api/map" | python3 -c 'import json,sys; m=json.load(sys.stdin); print("levels", [l["tiles"] for l in m["levels"]], "bounds", m["bounds_mm"])'
curl -s "${URL}api/reports" | python3 -c 'import json,sys; print([(r["name"], r["kind"], r["frames"]) for r in json.load(sys.stdin)])'
curl -s "${URL}api/reports/0" | python3 -c 'import json,sys; r=json.load(sys.stdin); m=r["metrics"]; print(r["fixes"], "fixes of", r["frames"], "frames; wrong fixes", m["wrong_fixes"], "; position RMS", m["position_rms_mm"], "mm")'
curl -s -o first-tile.png -w '%{http_code} %{content_type}\n' "${URL}api/tiles/5/0/-1.png"
kill -INT $SERVE
wait $SERVE
cat console.txt
