# Helpers for the PLC tests: the CLI helpers, plus a simulated site (map and run dataset on
# a real texture), free ports and waiting for a Modbus server.
source "$(dirname "$0")/../cli/lib.sh"
PLC_DIR="$(cd "$(dirname "$0")" && pwd)"
PYTHON=/usr/bin/python3   # Debian's interpreter, which has python3-pymodbus

require_peers() {
  if ! $PYTHON -c 'import pymodbus.server, pymodbus.client' 2>/dev/null; then
    echo "python3-pymodbus (with python3-serial-asyncio) is not installed: run scripts/install-deps.sh"
    exit 1
  fi
}

# A free TCP port on loopback.
free_port() { $PYTHON -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

# Seconds since the epoch, $1 seconds from now: the common start of a PLC and a run.
start_in() { $PYTHON -c "import time; print(f'{time.time() + $1:.6f}')"; }

# make_site NAME SPEED_MPS [procedural]: a 2 m straight on the asphalt texture (or the
# procedural floor, which never repeats), mapped at 0.5 m/s, and a run over it at SPEED_MPS, in
# $SCRATCH/NAME.mosaic and $SCRATCH/NAME-run.
make_site() {
  local texture="${MOSAICLOC_SHARED_DATA:-}/textures/asphalt_02_2048.jpg"
  if [ "${3:-}" = procedural ]; then
    texture=procedural
  elif [ ! -f "$texture" ]; then
    echo "shared data folder with real textures not found (MOSAICLOC_SHARED_DATA=${MOSAICLOC_SHARED_DATA:-unset}): skipped"
    exit 77
  fi
  printf 'route: {straight_length_m: 2.0, stop_s: 0.7}\n' > "$SCRATCH/site.yaml"
  "$MOSAICLOC" --quiet simulate --out "$SCRATCH/$1-map" --config "$SCRATCH/site.yaml" --floor "$texture" \
    --route straight --laps 1 --speed-mps 0.5 --seed 31 >/dev/null || fail "simulate map run"
  "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/$1-map" --out "$SCRATCH/$1.mosaic" --poses groundtruth >/dev/null || fail "map build"
  "$MOSAICLOC" --quiet simulate --out "$SCRATCH/$1-run" --config "$SCRATCH/site.yaml" --floor "$texture" \
    --route straight --laps 1 --speed-mps "$2" --seed 32 >/dev/null || fail "simulate run"
}

# run_config FILE PORT [EXTRA_PLC_YAML]: a run configuration playing $SCRATCH/site-run.
run_config() {
  cat > "$1" <<YAML
map: $SCRATCH/site.mosaic
camera:
  source: dataset
  dataset: {path: $SCRATCH/site-run}
plc:
  port: $2
  response_timeout_ms: 30
  heartbeat_timeout_ms: 300
${3:-}
YAML
}

# wait_port PORT: until something listens on it (at most 5 s).
wait_port() {
  for _ in $(seq 100); do
    $PYTHON -c "import socket,sys; s=socket.socket(); sys.exit(s.connect_ex(('127.0.0.1',$1)))" && return 0
    sleep 0.05
  done
  fail "nothing listens on port $1"
}

# json_check FILE PYTHON_EXPRESSIONS...: each expression, with d the JSON of FILE, is true.
json_check() {
  local file=$1; shift
  $PYTHON - "$file" "$@" <<'PY' || fail "check on $file failed"
import json, sys
text = open(sys.argv[1]).read().strip()
try:
    d = json.loads(text)
except json.JSONDecodeError:  # one object per line: the last one
    d = json.loads(text.splitlines()[-1])
d = d.get("summary", d)
ok = True
for expression in sys.argv[2:]:
    if not eval(expression, {"d": d}):
        print("not true:", expression, "in", {k: v for k, v in d.items() if k != "fixes"})
        ok = False
sys.exit(0 if ok else 1)
PY
}

# check_recorded_fixes RECORDING PLAYED [RMS_MM]: every visual fix the run recorded is within
# the replay accuracy of the ground truth (RMS at most RMS_MM, default 0.02 mm; recorded
# frame k is the played dataset's frame k).
check_recorded_fixes() {
  $PYTHON - "$1" "$2" "${3:-0.02}" <<'PY' || fail "recorded fixes of $1 are off the ground truth"
import bisect, math, sys
rec, run, bound = sys.argv[1], sys.argv[2], float(sys.argv[3])
def rows(path):
    return [l.strip().split(",") for l in open(path) if l.strip() and not l.startswith("#")]
recorded = [int(r[0]) for r in rows(rec + "/cam0/data.csv")]
played = [int(r[0]) for r in rows(run + "/cam0/data.csv")]
truth = []
for l in open(run + "/groundtruth/data.tum"):
    if l.startswith("#") or not l.strip():
        continue
    v = [float(x) for x in l.split()]
    truth.append((round(v[0] * 1e9), v[1] * 1000.0, v[2] * 1000.0))
times = [t for t, _, _ in truth]
errors = []
for r in rows(rec + "/fixes/data.csv"):
    if r[6] != "1":  # a frame without a visual fix: the dead-reckoned estimate
        continue
    k = recorded.index(int(r[0]))
    t = played[k]
    i = min(max(bisect.bisect_left(times, t), 1), len(truth) - 1)
    (t0, x0, y0), (t1, x1, y1) = truth[i - 1], truth[i]
    a = (t - t0) / (t1 - t0)
    errors.append(math.hypot(float(r[1]) - (x0 + a * (x1 - x0)), float(r[2]) - (y0 + a * (y1 - y0))))
rms = math.sqrt(sum(e * e for e in errors) / len(errors))
print(f"recorded fixes: {len(errors)} of {len(recorded)} frames, rms {rms:.4f} mm, max {max(errors):.4f} mm")
assert len(errors) >= 0.95 * len(played), len(errors)
assert rms <= bound and max(errors) <= 0.5, (rms, max(errors))
PY
}

# run_with_plc CONFIG DATASET PORT [RUN_ARGS...]: `mosaicloc run --config CONFIG` against a
# pymodbus PLC serving DATASET's encoder counts on PORT, both started at the same instant
# 2 s from now. The run's JSON lines end up in $SCRATCH/run.jsonl (its last line printed),
# the PLC's report in $SCRATCH/plc.json.
run_with_plc() {
  local config=$1 dataset=$2 port=$3
  shift 3
  local start
  start=$(start_in 2.0)
  $PYTHON "$PLC_DIR/pymodbus_plc.py" --dataset "$dataset" --port "$port" --start-unix "$start" \
    --request-period-ms 200 --out "$SCRATCH/plc.json" 2>"$SCRATCH/plc.err" &
  local plc=$!
  wait_port "$port"
  expect_exit 0 timeout 60 "$MOSAICLOC" --json run --config "$config" --start-unix "$start" "$@"
  cp "$SCRATCH/out" "$SCRATCH/run.jsonl"
  wait $plc || fail "the pymodbus PLC failed: $(tail -3 "$SCRATCH/plc.err")"
  tail -1 "$SCRATCH/run.jsonl"
}

# The console's page in a real browser (Debian's chromium, headless).
browse() {  # URL [SCREENSHOT]: the page's DOM once its requests are done, as chromium sees it
  local shot=()
  [ -n "${2:-}" ] && shot=(--screenshot="$2")
  timeout 60 chromium --headless --no-sandbox --disable-gpu --window-size=900,500 --virtual-time-budget=8000 \
    "${shot[@]}" --dump-dom "$1" 2>/dev/null
}
dom_check() {  # DOM_FILE PYTHON_EXPRESSIONS...: each true, with `data` the body's data-* and `dom` the text
  $PYTHON - "$@" <<'PY' || fail "the page in chromium: $1"
import re, sys
dom = open(sys.argv[1]).read()
body = re.search(r"<body([^>]*)>", dom).group(1)
data = {k: v for k, v in re.findall(r'data-([a-z-]+)="([^"]*)"', body)}
ok = True
for expression in sys.argv[2:]:
    if not eval(expression, {"data": data, "dom": dom, "re": re}):
        print("not true:", expression, "with", data, re.findall(r'<p id="error"[^>]*>([^<]*)', dom))
        ok = False
sys.exit(0 if ok else 1)
PY
}
