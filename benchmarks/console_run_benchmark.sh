#!/usr/bin/env bash
# `mosaicloc run` with and without a console client, alternating, on one drive: does a client
# slow tracking? The client holds the live stream open, polls /api/live and fetches tiles as
# fast as one connection allows. Figures: the tracking thread's processing time per frame and
# the capture-to-fix latency (p50, p99), frames processed and fixes, per run and as medians.
# Real time (the drive is played at its own speed against a PLC simulator): run it on a quiet
# machine.
#   benchmarks/console_run_benchmark.sh [MOSAICLOC] [WORK] [ROUNDS]
set -euo pipefail
MOSAICLOC=$(realpath "${1:-build/dev/app/mosaicloc}")
WORK=${2:-/tmp/console-run-benchmark}
ROUNDS=${3:-3}
PYTHON=/usr/bin/python3
mkdir -p "$WORK"
cd "$WORK"
free_port() { $PYTHON -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
if [ ! -f site.mosaic ]; then
  printf 'route: {straight_length_m: 8.0, stop_s: 0.5}\n' > site.yaml
  "$MOSAICLOC" --quiet simulate --out site-map --config site.yaml --floor procedural --route straight --laps 1 \
    --speed-mps 0.5 --seed 31 >/dev/null
  "$MOSAICLOC" --quiet map build --dataset site-map --out site.mosaic --poses groundtruth >/dev/null
  "$MOSAICLOC" --quiet simulate --out site-run --config site.yaml --floor procedural --route straight --laps 1 \
    --speed-mps 1.5 --seed 32 >/dev/null
fi
run_once() {  # MODE (without|with): one run; its summary's figures on one line
  local plc_port console_port start client=""
  plc_port=$(free_port)
  console_port=$(free_port)
  {
    printf 'map: %s/site.mosaic\ncamera: {source: dataset, dataset: {path: %s/site-run}}\nplc: {port: %s}\n' \
      "$WORK" "$WORK" "$plc_port"
    [ "$1" = with ] && printf 'console: {enabled: true, listen: "127.0.0.1:%s"}\n' "$console_port"
  } > run.yaml
  start=$($PYTHON -c 'import time; print(f"{time.time() + 2.0:.6f}")')
  "$MOSAICLOC" --quiet plc-sim --dataset site-run --port "$plc_port" --start-unix "$start" >/dev/null 2>&1 &
  local plc=$!
  sleep 0.5
  if [ "$1" = with ]; then
    $PYTHON - "$console_port" <<'PY' &
import http.client, random, sys, threading, time
port = int(sys.argv[1])
def connect():
    while True:
        try:
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=5); c.connect(); return c
        except OSError:
            time.sleep(0.05)
def stream():
    try:
        c = connect(); c.request("GET", "/api/live/stream"); r = c.getresponse()
        while r.read(256): pass
    except Exception:
        pass  # the run ended
def poll():
    c = connect()
    tiles = []
    c.request("GET", "/api/map"); info = __import__("json").loads(c.getresponse().read())
    for col, row in info["mapped_tiles"]["tiles"]:
        tiles.append(f"/api/tiles/{info['mapped_tiles']['level']}/{col}/{row}.png")
    count = 0
    while True:
        for path in ["/api/live"] + random.sample(tiles, min(4, len(tiles))):
            try:
                c.request("GET", path); c.getresponse().read()
                count += 1
                if count % 500 == 0:
                    open("client-requests.txt", "w").write(str(count))
            except Exception:
                return
threading.Thread(target=stream, daemon=True).start()
poll()
PY
    client=$!
  fi
  "$MOSAICLOC" --json run --config run.yaml --start-unix "$start" 2>/dev/null | tail -1 > summary.json
  [ -n "$client" ] && kill "$client" 2>/dev/null || true
  [ -n "$client" ] && echo "client: $(cat client-requests.txt 2>/dev/null || echo 0)+ requests during the run" >&2
  wait "$plc" 2>/dev/null || true
  $PYTHON -c 'import json,sys; d=json.load(open("summary.json"))["summary"]; print(sys.argv[1], d["processing_p50_ms"], d["processing_p99_ms"], d["latency_p50_ms"], d["latency_p99_ms"], d["frames_processed"], d["fixes"])' "$1" >> rounds.txt
}
rm -f rounds.txt
for round in $(seq "$ROUNDS"); do
  run_once without
  run_once with
done
$PYTHON - rounds.txt <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
print(f"{'client':8} {'proc p50 ms':>11} {'proc p99 ms':>11} {'lat p50 ms':>10} {'lat p99 ms':>10} {'frames':>7} {'fixes':>6}")
for r in rows:
    print(f"{r[0]:8} {float(r[1]):11.3f} {float(r[2]):11.3f} {float(r[3]):10.3f} {float(r[4]):10.3f} {r[5]:>7} {r[6]:>6}")
med = {m: [statistics.median(float(r[i]) for r in rows if r[0] == m) for i in (1, 2, 3, 4)] for m in ("without", "with")}
for m in ("without", "with"):
    print(f"median {m:8} processing p50 {med[m][0]:.3f} ms, p99 {med[m][1]:.3f} ms; latency p50 {med[m][2]:.3f}, p99 {med[m][3]:.3f} ms")
print(f"with / without: processing p50 {med['with'][0] / med['without'][0]:.3f}, p99 {med['with'][1] / med['without'][1]:.3f}")
PY
