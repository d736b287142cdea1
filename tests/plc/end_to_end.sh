# The live system end to end on loopback, against an independent PLC (pymodbus): the PLC
# serves a simulated run's encoder ticks in real time, `mosaicloc run` plays the run's frames
# as its camera, localizes on the map and answers the PLC's fix requests. Then the same with
# mosaicloc as the Modbus server and the PLC as the client, in the other word order.
source "$(dirname "$0")/lib.sh"
require_peers
make_site site 1.0

# --- mosaicloc polls the PLC (client role), word order high word first.
PORT=$(free_port)
run_config "$SCRATCH/run.yaml" "$PORT"
run_with_plc "$SCRATCH/run.yaml" "$SCRATCH/site-run" "$PORT" --record "$SCRATCH/rec"
json_check "$SCRATCH/run.jsonl" 'd["fix_rate"] >= 0.95' 'd["lock_losses"] == 0' 'd["requests"] >= 10' \
  'd["answered"] == d["requests"]' 'd["plc_read_errors"] == 0' 'd["plc_write_errors"] == 0' \
  'd["stopped"] == "the camera source ended"' 'abs(d["wheel_scale_left_percent"]) < 10' \
  'abs(d["wheel_scale_right_percent"]) < 10' '"steering_offset_error_deg" not in d'
$PYTHON -c 'import json,sys; d=json.load(open(sys.argv[1])); d.pop("fixes"); print("PLC:", d)' "$SCRATCH/plc.json"
# The PLC got an echoed answer to its requests, standing still exact, moving within the
# time-stamp error of the link (the pose is for the instant it was written). Tracking all the
# way, but for at most three answers marked degraded: on a loaded machine the first fix after
# the vehicle starts (at 0.7 s) is sometimes gated out (NIS 17.6 against 16.3 seen), the live
# prediction still standing where the wheels already turned; never lost or off the map.
json_check "$SCRATCH/plc.json" 'd["answered"] >= d["requests"] - 3' 'd["answered"] >= 10' \
  'd["still_fixes"] >= 5' 'd["still_max_error_mm"] <= 0.1' 'd["moving_fixes"] >= 5' \
  'd["moving_max_error_per_speed_ms"] <= 150' 'all(f["status"] in (0, 1, 2) for f in d["fixes"])' \
  'sum(f["status"] == 2 for f in d["fixes"]) <= 3' \
  'all(f["status"] in (1, 2) for f in d["fixes"] if f["t_s"] > 0.5)'
check_recorded_fixes "$SCRATCH/rec" "$SCRATCH/site-run"
# The recording replays offline.
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/rec" --map "$SCRATCH/site.mosaic" \
  --out "$SCRATCH/rec-report"
json_check "$SCRATCH/rec-report/metrics.json" 'd["fix_rate"] >= 0.95' 'd["lock_losses"] == 0'

# --- the PLC writes to mosaicloc (server role), word order low word first.
PORT=$(free_port)
run_config "$SCRATCH/server.yaml" "$PORT" "  role: server
  registers: {word_order: low_first}"
START=$(start_in 2.0)
$PYTHON "$PLC_DIR/pymodbus_plc.py" --role client --word-order low_first --dataset "$SCRATCH/site-run" \
  --port "$PORT" --start-unix "$START" --request-period-ms 200 --out "$SCRATCH/plc-client.json" \
  2>"$SCRATCH/plc-client.err" &
PLC=$!
expect_exit 0 timeout 60 "$MOSAICLOC" --json run --config "$SCRATCH/server.yaml" --start-unix "$START"
cp "$SCRATCH/out" "$SCRATCH/server.jsonl"
wait $PLC || fail "the pymodbus PLC client failed: $(tail -3 "$SCRATCH/plc-client.err")"
tail -1 "$SCRATCH/server.jsonl"
json_check "$SCRATCH/server.jsonl" 'd["fix_rate"] >= 0.95' 'd["lock_losses"] == 0' 'd["requests"] >= 10' \
  'd["answered"] == d["requests"]'
$PYTHON -c 'import json,sys; d=json.load(open(sys.argv[1])); d.pop("fixes"); print("PLC client:", d)' \
  "$SCRATCH/plc-client.json"
json_check "$SCRATCH/plc-client.json" 'd["answered"] >= 10' 'd["still_fixes"] >= 5' 'd["still_max_error_mm"] <= 0.1' \
  'd["moving_max_error_per_speed_ms"] <= 150'
finish
