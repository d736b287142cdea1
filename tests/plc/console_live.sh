# The console inside `run` (run.yaml console:), against a pymodbus PLC: the live pose reaches a
# script (/api/live) and a real browser's page (Debian's chromium, headless). Real time: the run
# must keep up with the camera and the PLC.
source "$(dirname "$0")/lib.sh"
require_peers
command -v chromium >/dev/null || { fail "chromium is not installed (scripts/install-deps.sh installs it)"; finish; }
make_site site 0.25 procedural
PLC_PORT=$(free_port)
CONSOLE_PORT=$(free_port)
cat > "$SCRATCH/run.yaml" <<YAML
map: $SCRATCH/site.mosaic
camera:
  source: dataset
  dataset: {path: $SCRATCH/site-run}
plc: {port: $PLC_PORT, response_timeout_ms: 30, heartbeat_timeout_ms: 300}
console: {enabled: true, listen: "127.0.0.1:$CONSOLE_PORT"}
YAML
START=$(start_in 3.0)
$PYTHON "$PLC_DIR/pymodbus_plc.py" --dataset "$SCRATCH/site-run" --port "$PLC_PORT" --start-unix "$START" \
  --out "$SCRATCH/plc.json" >/dev/null 2>"$SCRATCH/plc.err" &
PLC=$!
wait_port "$PLC_PORT"
"$MOSAICLOC" --json run --config "$SCRATCH/run.yaml" --start-unix "$START" >"$SCRATCH/run.jsonl" 2>"$SCRATCH/run.err" &
RUN=$!
wait_port "$CONSOLE_PORT"
# Once the drive has started: the state as a script reads it, and the page following live
# updates (20 Hz) for as long as headless chromium's virtual time lets it (about half a second
# of real time: a few updates, not a fixed number). The drive lasts about 12 s (0.25 m/s), so the run
# is still going when a slow browser start has the page ask for it.
sleep 3.8
curl -sf "http://127.0.0.1:$CONSOLE_PORT/api/live" > "$SCRATCH/live.json" || fail "GET /api/live during the run"
browse "http://127.0.0.1:$CONSOLE_PORT/?follow=20" > "$SCRATCH/live.html"
wait $RUN || fail "run failed: $(tail -3 "$SCRATCH/run.err")"
wait $PLC || fail "the pymodbus PLC failed: $(tail -3 "$SCRATCH/plc.err")"
dom_check "$SCRATCH/live.html" 'int(data.get("live-updates", 0)) >= 3' 'dom.count("live-pose") >= 1' \
  're.search(r"id=\"live-lock\" class=\"lock-1\">tracking<", dom)'
json_check "$SCRATCH/live.json" 'd["live"] is True' 'd["known"] is True' 'd["frames"] > 5' 'd["lock"] == 1' \
  'len(d["path"]) > 2' 'd["x_mm"] > 0'
json_check "$SCRATCH/run.jsonl" 'd["fix_rate"] >= 0.95'
finish
