#!/usr/bin/env bash
# A live run of MINUTES (60 by default) at real time: `mosaicloc run` with the simulator as its
# camera (each frame rendered when it is due) against `mosaicloc plc-sim` playing the same
# drive's encoder counts over Modbus TCP and asking for a fix every 500 ms. The drive: the 85 m
# network route at 1.5 m/s on the asphalt texture with 2 % / 2.5 % wheel radius errors, over a
# map built from one slow mapping lap (frames and encoders only), so every other lap leaves the
# map on lanes the mapping lap did not take. Every 10 s the run's resident memory, threads and
# open file descriptors are sampled from /proc, the memory split into anonymous, file-backed
# and shared (and, whenever the number of descriptors changes, what they are: descriptors.txt).
# Prints the run's summary, the PLC's view of the fixes (against the truth after
# the best rigid alignment of the map's frame) and the
# resources: first and last, and the memory's least-squares slope after the first tenth, also
# of the heap in use and the map's decoded tiles (from the run's status lines).
# CONTEND=1 starves the run of the CPU now and then, as other work on a vehicle's computer
# does: every 4 s, three busy loops at a higher priority (nice -10) for 0.2 to 1 s. The PLC
# simulator always runs above them all, every thread of it, at a real-time priority from its
# start: it stands for the PLC, which has a CPU of its own, changes its counters on time and
# takes a write when it arrives. (Reniced after its start, the thread that serves the registers
# kept the run's priority; at any nice value a woken thread may wait a scheduler tick, 4 ms,
# behind a busy one, and the writes it took that late were counted 6 mm off at 1.5 m/s.)
# Needs root.
# PLC_PRIORITY=N runs the PLC thread at SCHED_FIFO priority N (plc.thread_priority).
# Usage: [CONTEND=1] [PLC_PRIORITY=N] benchmarks/live_hour.sh [MOSAICLOC] [WORK_DIR] [MINUTES]
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
printf 'map: %s\ncamera: {source: simulator, simulator: {config: %s}}\nplc: {port: %s, thread_priority: %s}\n' \
  "$WORK/map.mosaic" "$WORK/drive.yaml" "$port" "${PLC_PRIORITY:-0}" > "$WORK/run.yaml"
start=$("$PYTHON" -c 'import time; print(f"{time.time() + 8.0:.6f}")')
# Every thread of the PLC simulator at a real-time priority (SCHED_FIFO 20), or where that is
# refused at nice -15 (see above).
plc_priority=(chrt -f 20)
chrt -f 20 true 2>/dev/null || plc_priority=(nice -n -15)
"${plc_priority[@]}" "$MOSAICLOC" --quiet --json plc-sim --simulate "$WORK/drive.yaml" --port "$port" --start-unix "$start" \
  --request-period-ms 500 --fixes-out "$WORK/plc-fixes.csv" > "$WORK/plc.json" 2> "$WORK/plc.err" &
plc=$!
"$MOSAICLOC" --json run --config "$WORK/run.yaml" --start-unix "$start" > "$WORK/run.jsonl" 2> "$WORK/run.err" &
run=$!
case "$(ps -o cls=,nice= -p "$plc" | tr -s ' ')" in
  *FF*|*-15) ;;
  *) echo "plc-sim could not be given a higher priority: its counters may change and its writes arrive late" ;;
esac
if [ "${CONTEND:-0}" = 1 ]; then
  (
    i=0
    while kill -0 "$run" 2>/dev/null; do
      sleep 4
      ms=$((200 + (i * 373) % 800)); i=$((i + 1))
      for _ in 1 2 3; do nice -n -10 timeout "$(awk "BEGIN {print $ms / 1000}")" bash -c 'while :; do :; done' & done
      wait
    done
  ) &
fi
# Resident memory split as the kernel counts it: anonymous (the heap, stacks, the allocator's
# arenas), file-backed (the program, its libraries, mapped files) and shared memory (SQLite's
# WAL index).
echo "# wall_s rss_mib threads fds anon_mib file_mib shmem_mib" > "$WORK/resources.txt"
t0=$(date +%s)
while kill -0 "$run" 2>/dev/null; do
  if [ -r "/proc/$run/status" ]; then
    sample=$(awk '/^VmRSS/{r=$2} /^Threads/{t=$2} /^RssAnon/{a=$2} /^RssFile/{f=$2} /^RssShmem/{s=$2}
                  END {if (r != "") print r / 1024, t, a / 1024, f / 1024, s / 1024}' "/proc/$run/status" 2>/dev/null || true)
    fds=$(ls "/proc/$run/fd" 2>/dev/null | wc -l)
    # What the descriptors are, whenever their number changes (descriptors.txt).
    if [ "$fds" != "${last_fds:-}" ]; then
      { echo "== $(( $(date +%s) - t0 )) s: $fds"; ls -l "/proc/$run/fd" 2>/dev/null | awk 'NR > 1 {print $9, $11}'; } \
        >> "$WORK/descriptors.txt"
      last_fds=$fds
    fi
    if [ -n "$sample" ]; then
      set -- $sample
      echo "$(( $(date +%s) - t0 )) $1 $2 $fds $3 $4 $5" >> "$WORK/resources.txt"
    fi
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
keys = ("frames", "frames_processed", "frames_dropped", "fix_rate", "lock_losses", "relocalizations", "reanchorings", "requests",
        "answered", "answer_max_ms", "latency_p50_ms", "latency_p99_ms", "processing_p99_ms", "encoder_samples",
        "encoder_rejected", "encoder_late_updates", "plc_timeouts", "plc_read_errors", "plc_write_errors", "frames_by_mode", "stopped")
print("run:", {k: summary.get(k) for k in keys})
print("plc-sim:", {k: plc.get(k) for k in ("fixes_received", "requests", "answered", "answer_p99_ms", "answer_max_ms",
                                           "position_rms_mm", "position_max_mm")})
rows = [l.split() for l in open(f"{work}/resources.txt") if not l.startswith("#")]
t = [float(r[0]) for r in rows]; rss = [float(r[1]) for r in rows]
th = [int(r[2]) for r in rows]; fd = [int(r[3]) for r in rows]
after = [i for i in range(len(t)) if t[i] >= 0.1 * t[-1]]
def slope_of(v):
    n = len(after); mt = sum(t[i] for i in after) / n; mv = sum(v[i] for i in after) / n
    return 3600 * sum((t[i] - mt) * (v[i] - mv) for i in after) / max(1e-9, sum((t[i] - mt) ** 2 for i in after))
print(f"resources: {len(rows)} samples over {t[-1] / 60:.1f} min; RSS {rss[0]:.1f} -> {rss[-1]:.1f} MiB "
      f"(max {max(rss):.1f}), slope after the first tenth {slope_of(rss):.2f} MiB/h; threads {th[0]} -> {th[-1]} "
      f"(max {max(th)}); fds {fd[0]} -> {fd[-1]} (max {max(fd)})")
print("resident, split: " + "; ".join(
    f"{name} {float(rows[0][col]):.1f} -> {float(rows[-1][col]):.1f} MiB, slope {slope_of([float(r[col]) for r in rows]):+.2f} MiB/h"
    for name, col in (("anonymous", 4), ("file-backed", 5), ("shared memory", 6))))
# What grows, from the run's own status lines (one a second): the map's decoded tiles, the rest
# of the heap, and what the allocator holds beyond the heap in use.
lines = [json.loads(l) for l in open(f"{work}/run.jsonl") if '"rss_mib"' in l]
if lines:
    def fit(key):
        pts = [(l["t_s"], l[key]) for l in lines if l["t_s"] >= 0.1 * lines[-1]["t_s"]]
        mx = sum(p[0] for p in pts) / len(pts); my = sum(p[1] for p in pts) / len(pts)
        return 3600 * sum((p[0] - mx) * (p[1] - my) for p in pts) / max(1e-9, sum((p[0] - mx) ** 2 for p in pts))
    first, last = lines[0], lines[-1]
    print("memory (status lines): " + "; ".join(
        f"{key} {first[key]:.1f} -> {last[key]:.1f} MiB, slope {fit(key):+.2f} MiB/h"
        for key in ("rss_mib", "heap_mib", "map_cache_mib")))
PY
# The fixes the PLC received, in the map's frame: a built map's frame is the truth's up to a
# small rigid offset, found from the tracking fixes (status 1). By status: how many, how far off
# (p50, p99, max) and how many more than 1 mm and 5 mm off (a tracking fix that far off is a
# wrong fix: the PLC has no reason to doubt it).
"$PYTHON" - "$WORK/plc-fixes.csv" <<'PY'
import math, sys
rows = []
for line in open(sys.argv[1]):
    f = line.strip().split(",")
    if line.startswith("#") or f[10] in ("", "nan"):
        continue
    rows.append((float(f[1]), float(f[2]), int(f[4]), float(f[8]), float(f[9])))
good = [r for r in rows if r[2] == 1]
n = len(good)
mp = [sum(r[i] for r in good) / n for i in (0, 1)]
mq = [sum(r[3 + i] for r in good) / n for i in (0, 1)]
dot = sum((r[0] - mp[0]) * (r[3] - mq[0]) + (r[1] - mp[1]) * (r[4] - mq[1]) for r in good)
cross = sum((r[0] - mp[0]) * (r[4] - mq[1]) - (r[1] - mp[1]) * (r[3] - mq[0]) for r in good)
c, s = math.cos(math.atan2(cross, dot)), math.sin(math.atan2(cross, dot))
by = {}
for x, y, status, gx, gy in rows:
    a = (x - mp[0], y - mp[1])
    by.setdefault(status, []).append(math.hypot(c * a[0] - s * a[1] + mq[0] - gx, s * a[0] + c * a[1] + mq[1] - gy))
names = {1: "tracking", 2: "degraded", 3: "lost", 4: "off-map", 5: "searching"}
print("fixes the PLC received, after the best rigid alignment of the tracking ones (mm):")
for status in sorted(by):
    e = sorted(by[status]); k = len(e)
    print(f"  status {status} {names.get(status, '?'):9s} {k:6d} fixes  p50 {e[k // 2]:.3f}  p99 {e[min(k - 1, int(0.99 * k))]:.3f}"
          f"  max {e[-1]:.3f}  >1 mm {sum(v > 1 for v in e)}  >5 mm {sum(v > 5 for v in e)}")
PY
