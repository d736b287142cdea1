# A PLC that does not answer for about 100 ms (answers later than the response timeout, then
# a reconnection) while the vehicle accelerates: the counters read after the outage carry the
# motion over the gap (plc.odometry_bridge_ms), the frames in it wait for them, and no sample
# is rejected and no lock lost. Longer outages, where the counters are forgotten, are the
# faults test's.
source "$(dirname "$0")/lib.sh"
require_peers
make_site site 1.0
PORT=$(free_port)
run_config "$SCRATCH/run.yaml" "$PORT" "  odometry_bridge_ms: 200.0"
START=$(start_in 2.0)
$PYTHON "$PLC_DIR/pymodbus_plc.py" --dataset "$SCRATCH/site-run" --port "$PORT" --start-unix "$START" \
  --request-period-ms 200 --delay 1.1:1.2:60 --out "$SCRATCH/plc.json" 2>"$SCRATCH/plc.err" &
PLC=$!
wait_port "$PORT"
expect_exit 0 timeout 60 "$MOSAICLOC" --json run --config "$SCRATCH/run.yaml" --start-unix "$START"
cp "$SCRATCH/out" "$SCRATCH/run.jsonl"
wait $PLC || fail "the pymodbus PLC failed: $(tail -3 "$SCRATCH/plc.err")"
tail -1 "$SCRATCH/run.jsonl"
expect_in "$SCRATCH/err" "timed out"
expect_in "$SCRATCH/err" "the counters bridge the gap"
json_check "$SCRATCH/run.jsonl" 'd["odometry_outages"] >= 1' 'd["plc_timeouts"] >= 1' 'd["lock_losses"] == 0' \
  'd["encoder_rejected"] == 0' 'd["fix_rate"] >= 0.95' 'd["answered"] == d["requests"]'
json_check "$SCRATCH/plc.json" 'd["still_max_error_mm"] <= 0.1' 'all(f["status"] in (0, 1, 2) for f in d["fixes"])'
finish
