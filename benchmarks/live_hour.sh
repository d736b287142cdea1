#!/usr/bin/env bash
# A live run of MINUTES (60 by default) at real time: `mosaicloc run` with the simulator as its
# camera (each frame rendered when it is due) against `mosaicloc plc-sim` playing the same
# drive's encoder counts over Modbus TCP and asking for a fix every 500 ms. The drive: the 85 m
# network route at 1.5 m/s on the asphalt texture with 2 % / 2.5 % wheel radius errors, over a
# map built from one slow mapping lap (frames and encoders only), so every other lap leaves the
# map on lanes the mapping lap did not take. Every 10 s the run's resident memory, threads and
# open file descriptors are sampled from /proc. Prints the run's summary, the PLC's view of the
# fixes (against the truth after the best rigid alignment of the map's frame) and the
# resources: first and last, and the memory's least-squares slope after the first tenth.
# Usage: benchmarks/live_hour.sh [MOSAICLOC] [WORK_DIR] [MINUTES]
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
MINUTES=${3:-60}
TEXTURE=${MOSAICLOC_SHARED_DATA:-$HERE/../shared/data}/textures/asphalt_02_2048.jpg
PYTHON=/usr/bin/python3
[ -f "$TEXTURE" ] || { echo "$TEXTURE is absent"; exit 1; }
mkdir -p "$WORK"

if [ ! -f "$WORK/map.mosaic" ]; then
  printf 'route: {name: network, network_scale: 1.0, speed_mps: 0.5, max_accel_mps2: 1.0}\nrun: {laps: 1, seed: 81}\n' \
    > "$WORK/map.yaml"
  "$MOSAICLOC" -q simulate --out "$WORK/mapping" --overwrite --config "$WORK/map.yaml" --floor "$TEXTURE" >/dev/null
  "$MOSAICLOC" -q map build --dataset "$WORK/mapping" --out "$WORK/map.mosaic" --overwrite >/dev/null
fi
cat > "$WORK/drive.yaml" <<YAML
floor: {kind: image, image: $TEXTURE}
route: {name: network, network_scale: 1.0, speed_mps: 1.5, max_accel_mps2: 3.0}
encoders: {left_radius_error: 0.02, right_radius_error: 0.025}
run: {frames: $((MINUTES * 60 * 30)), seed: 86}
YAML
port=$("$PYTHON" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
printf 'map: %s\ncamera: {source: simulator, simulator: {config: %s}}\nplc: {port: %s}\n' \
  "$WORK/map.mosaic" "$WORK/drive.yaml" "$port" > "$WORK/run.yaml"
start=$("$PYTHON" -c 'import time; print(f"{time.time() + 8.0:.6f}")')
"$MOSAICLOC" --quiet --json plc-sim --simulate "$WORK/drive.yaml" --port "$port" --start-unix "$start" \
  --request-period-ms 500 --fixes-out "$WORK/plc-fixes.csv" > "$WORK/plc.json" 2> "$WORK/plc.err" &
plc=$!
"$MOSAICLOC" --json run --config "$WORK/run.yaml" --start-unix "$start" > "$WORK/run.jsonl" 2> "$WORK/run.err" &
run=$!
echo "# wall_s rss_mib threads fds" > "$WORK/resources.txt"
t0=$(date +%s)
while kill -0 "$run" 2>/dev/null; do
  if [ -r "/proc/$run/status" ]; then
    rss=$(awk '/^VmRSS/{print $2 / 1024}' "/proc/$run/status" 2>/dev/null || true)
    threads=$(awk '/^Threads/{print $2}' "/proc/$run/status" 2>/dev/null || true)
    fds=$(ls "/proc/$run/fd" 2>/dev/null | wc -l)
    [ -n "$rss" ] && echo "$(( $(date +%s) - t0 )) $rss $threads $fds" >> "$WORK/resources.txt"
  fi
  sleep 10
done
wait "$run" || echo "run exited $?: $(tail -3 "$WORK/run.err")"
wait "$plc" || echo "plc-sim exited $?: $(tail -3 "$WORK/plc.err")"

"$PYTHON" - "$WORK" <<'PY'
import json, sys
work = sys.argv[1]
summary = json.loads(open(f"{work}/run.jsonl").read().strip().splitlines()[-1])["summary"]
plc = json.load(open(f"{work}/plc.json"))
keys = ("frames", "frames_processed", "frames_dropped", "fix_rate", "lock_losses", "relocalizations", "requests",
        "answered", "answer_max_ms", "latency_p50_ms", "latency_p99_ms", "processing_p99_ms", "encoder_samples",
        "encoder_rejected", "plc_timeouts", "plc_read_errors", "plc_write_errors", "frames_by_mode", "stopped")
print("run:", {k: summary.get(k) for k in keys})
print("plc-sim:", {k: plc.get(k) for k in ("fixes_received", "requests", "answered", "answer_p99_ms", "answer_max_ms",
                                           "position_rms_mm", "position_max_mm")})
rows = [l.split() for l in open(f"{work}/resources.txt") if not l.startswith("#")]
t = [float(r[0]) for r in rows]; rss = [float(r[1]) for r in rows]
th = [int(r[2]) for r in rows]; fd = [int(r[3]) for r in rows]
after = [i for i in range(len(t)) if t[i] >= 0.1 * t[-1]]
n = len(after); mt = sum(t[i] for i in after) / n; mr = sum(rss[i] for i in after) / n
slope = sum((t[i] - mt) * (rss[i] - mr) for i in after) / max(1e-9, sum((t[i] - mt) ** 2 for i in after))
print(f"resources: {len(rows)} samples over {t[-1] / 60:.1f} min; RSS {rss[0]:.1f} -> {rss[-1]:.1f} MiB "
      f"(max {max(rss):.1f}), slope after the first tenth {slope * 3600:.2f} MiB/h; threads {th[0]} -> {th[-1]} "
      f"(max {max(th)}); fds {fd[0]} -> {fd[-1]} (max {max(fd)})")
PY
# The fixes the PLC received, in the map's frame: a built map's frame is the truth's up to a
# small rigid offset (benchmarks/aligned.py).
"$PYTHON" - "$WORK/plc-fixes.csv" "$WORK/fixes.tum" "$WORK/truth.tum" <<'PY'
import sys
fixes, truth = open(sys.argv[2], "w"), open(sys.argv[3], "w")
for line in open(sys.argv[1]):
    if line.startswith("#"):
        continue
    f = line.strip().split(",")
    if f[4] in ("1", "2") and f[8] != "nan" and f[8] != "":
        print(f"{f[0]} {float(f[1]) / 1000:.7f} {float(f[2]) / 1000:.7f} 0 0 0 0 1", file=fixes)
        print(f"{float(f[0]) - 1e-6} {float(f[8]) / 1000:.7f} {float(f[9]) / 1000:.7f} 0 0 0 0 1", file=truth)
        print(f"{float(f[0]) + 1e-6} {float(f[8]) / 1000:.7f} {float(f[9]) / 1000:.7f} 0 0 0 0 1", file=truth)
PY
echo "fixes the PLC received (tracking or degraded), after the best rigid alignment: rms max mm" \
  "$("$PYTHON" "$HERE/benchmarks/aligned.py" "$WORK/fixes.tum" "$WORK/truth.tum")"
