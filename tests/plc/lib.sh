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

# make_site NAME SPEED_MPS: a 2 m straight on the asphalt texture, mapped at 0.5 m/s, and a
# run over it at SPEED_MPS, in $SCRATCH/NAME.mosaic and $SCRATCH/NAME-run.
make_site() {
  local texture="${MOSAICLOC_SHARED_DATA:-}/textures/asphalt_02_2048.jpg"
  if [ ! -f "$texture" ]; then
    echo "shared data folder with real textures not found (MOSAICLOC_SHARED_DATA=${MOSAICLOC_SHARED_DATA:-unset}): skipped"
    exit 77
  fi
  printf 'route: {straight_length_m: 2.0, stop_s: 0.7}\n' > "$SCRATCH/site.yaml"
  "$MOSAICLOC" --quiet simulate --out "$SCRATCH/$1-map" --config "$SCRATCH/site.yaml" --floor "$texture" \
    --route straight --laps 1 --speed-mps 0.5 --seed 31 >/dev/null || fail "simulate map run"
  "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/$1-map" --out "$SCRATCH/$1.mosaic" >/dev/null || fail "map build"
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
