# Faults on the PLC link, each detected, reported and survived: the PLC heartbeat freezes,
# the PLC asks for a relocalization (register 6), answers come later than the response
# timeout, the counters jump for a moment, and the PLC is killed and restarted (its counters
# back at 0, which is no request). The run must go on, flag odometry while it is unusable, and end
# localized as precisely as ever.
source "$(dirname "$0")/lib.sh"
require_peers
# The procedural floor: the relocalization the PLC asks for must find the one place the
# vehicle is at (over a floor that repeats it would rightly answer "ambiguous").
make_site site 0.5 procedural

PORT=$(free_port)
# Retries at most 200 ms apart: the restarted PLC (a Python process) may take a second to
# listen on a loaded machine, and the default backoff, doubling to 2 s, could then outlast
# the short run.
# The run does not know where it starts: it finds itself on the map through the place index.
run_config "$SCRATCH/run.yaml" "$PORT" "  reconnect_max_ms: 200.0
start: {unknown: true}"
START=$(start_in 2.0)
plc() {  # plc NAME: the pymodbus PLC with the faults, in the background
  $PYTHON "$PLC_DIR/pymodbus_plc.py" --dataset "$SCRATCH/site-run" --port "$PORT" --start-unix "$START" \
    --request-period-ms 200 --freeze-heartbeat 1.0:1.8 --delay 2.2:2.5:60 --spike 2.8 \
    --out "$SCRATCH/$1.json" "${@:2}" 2>"$SCRATCH/$1.err" &
}
plc first --relocalize-at 2.0
FIRST=$!
wait_port "$PORT"
"$MOSAICLOC" --json --log-level ${RUN_LOG:-info} run --config "$SCRATCH/run.yaml" --start-unix "$START" >"$SCRATCH/run.jsonl" 2>"$SCRATCH/run.err" &
RUN=$!
# Kill the PLC 3.2 s into the recording, and bring it back 0.6 s later.
sleep "$($PYTHON -c "import time; print(max(0.0, $START + 3.2 - time.time()))")"
kill -9 $FIRST
sleep 0.6
plc second
SECOND=$!
wait $RUN || fail "mosaicloc run did not survive the faults: $(tail -5 "$SCRATCH/run.err")"
wait $SECOND || fail "the restarted PLC failed: $(tail -3 "$SCRATCH/second.err")"
tail -1 "$SCRATCH/run.jsonl"
json_check "$SCRATCH/run.jsonl" 'd["stopped"] == "the camera source ended"' \
  'd["odometry_outages"] >= 2' 'd["plc_timeouts"] >= 1' 'd["encoder_rejected"] >= 1' \
  'd["plc_connects"] >= 2' 'd["plc_read_errors"] >= 1' 'd["fix_rate"] >= 0.8' \
  'd["relocalize_requests"] == 1' 'd["relocalizations"] >= 2'
expect_in "$SCRATCH/run.err" "run: the start is unknown: searching the whole map"
# Each fault was reported, naming what it concerned.
expect_in "$SCRATCH/run.err" "odometry invalid: the PLC heartbeat (plc_heartbeat (register 4)) has not changed"
expect_in "$SCRATCH/run.err" "holding registers 0-6 (left_ticks, right_ticks, plc_heartbeat, fix_request, relocalize_request)"
expect_in "$SCRATCH/run.err" "timed out"
expect_in "$SCRATCH/run.err" "encoder sample rejected"
expect_in "$SCRATCH/run.err" "odometry valid again"
expect_in "$SCRATCH/run.err" "the PLC asks for a relocalization (request 1)"
$PYTHON -c 'import json,sys; d=json.load(open(sys.argv[1])); d.pop("fixes"); print("restarted PLC:", d)' \
  "$SCRATCH/second.json"
# After everything, the vehicle standing at the end of the run is where the PLC is told.
json_check "$SCRATCH/second.json" 'd["answered"] >= 3' 'd["still_fixes"] >= 3' 'd["still_max_error_mm"] <= 0.1' \
  'd["fixes"][-1]["status"] == 1'
if [ "$FAILURES" -gt 0 ]; then  # what the run said, to tell a slow machine from a defect
  echo "--- the run's log (last 60 lines):" >&2; tail -60 "$SCRATCH/run.err" >&2
  echo "--- the restarted PLC's log:" >&2; tail -20 "$SCRATCH/second.err" >&2
fi
finish
