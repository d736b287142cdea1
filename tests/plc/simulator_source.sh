# The simulator as a live source: `run` renders a drive and plays its frames in real time while
# `plc-sim` plays the same drive's encoder counts (the simulator is deterministic). The vehicle
# is a tricycle: the PLC serves its drive wheel counter and its steering encoder (registers
# 0-1 and 2-3), and the run takes its kind from the drive. Then the same with Debian's pymodbus
# as the PLC.
source "$(dirname "$0")/lib.sh"
TEXTURE="${MOSAICLOC_SHARED_DATA:-}/textures/asphalt_02_2048.jpg"
if [ ! -f "$TEXTURE" ]; then
  echo "shared data folder with real textures not found (MOSAICLOC_SHARED_DATA=${MOSAICLOC_SHARED_DATA:-unset}): skipped"
  exit 77
fi
cat > "$SCRATCH/drive.yaml" <<YAML
floor: {kind: image, image: $TEXTURE}
route: {name: straight, straight_length_m: 2.0, stop_s: 0.7, speed_mps: 1.0, curvature_transition_m: 0.5,
        lateral_deviation_mm: 8.0}
vehicle: {kind: tricycle, drive_wheel_radius_mm: 100.0, wheelbase_mm: 1200.0, steering_ticks_per_revolution: 65536}
encoders: {drive_radius_error: 0.01, steering_offset_error_deg: 0.3}
run: {seed: 32, laps: 1}
YAML
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/map-run" --config "$SCRATCH/drive.yaml" --speed-mps 0.5 --seed 31 \
  >/dev/null || fail "simulate the mapping run"
"$MOSAICLOC" --quiet map build --dataset "$SCRATCH/map-run" --out "$SCRATCH/site.mosaic" --poses groundtruth >/dev/null || fail "map build"
PORT=$(free_port)
printf 'map: %s\ncamera: {source: simulator, simulator: {config: %s}}\nplc: {port: %s}\n' \
  "$SCRATCH/site.mosaic" "$SCRATCH/drive.yaml" "$PORT" > "$SCRATCH/run.yaml"
START=$(start_in 5.0)  # both sides plan the drive first (its path), which must be done by then
"$MOSAICLOC" --quiet --json plc-sim --simulate "$SCRATCH/drive.yaml" --port "$PORT" --start-unix "$START" \
  --request-period-ms 200 >"$SCRATCH/plc.json" 2>"$SCRATCH/plc.err" &
PLC=$!
expect_exit 0 timeout 60 "$MOSAICLOC" --json run --config "$SCRATCH/run.yaml" --start-unix "$START"
cp "$SCRATCH/out" "$SCRATCH/run.jsonl"
wait $PLC || fail "plc-sim failed: $(tail -3 "$SCRATCH/plc.err")"
tail -1 "$SCRATCH/run.jsonl"
json_check "$SCRATCH/run.jsonl" 'd["fix_rate"] >= 0.95' 'd["lock_losses"] == 0' 'd["answered"] >= 5' \
  'd["answered"] == d["requests"]' 'd["encoder_rejected"] == 0' 'd["encoder_samples"] >= 300' \
  'd["encoder_late_updates"] >= 0' 'abs(d["drive_wheel_scale_percent"]) < 10' 'abs(d["steering_offset_error_deg"]) < 5' '"wheel_scale_left_percent" not in d'
json_check "$SCRATCH/plc.json" 'd["answered"] >= 5' 'd["fixes_received"] >= 20'
# Every status line says what the process holds: memory, heap (near 0 under the sanitizers, whose
# allocators do not answer for it) and the map's decoded tiles, within the default budget.
"$PYTHON" - "$SCRATCH/run.jsonl" <<'PY' || fail "the status lines' memory"
import json, sys
lines = [json.loads(l) for l in open(sys.argv[1]) if l.strip() and '"summary"' not in l]
assert len(lines) >= 5, len(lines)
last = lines[-1]
assert 0 < last["map_cache_mib"] <= 256 + 4 and last["heap_mib"] >= 0 and last["rss_mib"] > 0, last
PY

# The same drive recorded, its counters served by an independent peer (Debian's pymodbus),
# which knows nothing of vehicle kinds: registers 0-3 carry whatever two counters the
# recording has, and the run reads them as the tricycle's that the recording says it is.
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/run-ds" --config "$SCRATCH/drive.yaml" >/dev/null || fail "simulate the drive"
PORT=$(free_port)
printf 'map: %s
camera: {source: dataset, dataset: {path: %s}}
plc: {port: %s}
' \
  "$SCRATCH/site.mosaic" "$SCRATCH/run-ds" "$PORT" > "$SCRATCH/peer.yaml"
run_with_plc "$SCRATCH/peer.yaml" "$SCRATCH/run-ds" "$PORT"
# The Python PLC updates its counters a few ms late now and then (its interpreter's
# scheduling), more than the stamps' 3 ms allow for while the steering swings: the filter's
# gate refuses the fixes that disagree with the prediction then (up to 6 of 132 seen).
json_check "$SCRATCH/run.jsonl" 'd["fix_rate"] >= 0.9' 'd["lock_losses"] == 0' 'd["answered"] == d["requests"]' \
  'd["encoder_rejected"] == 0' 'abs(d["steering_offset_error_deg"]) < 5'
json_check "$SCRATCH/plc.json" 'd["answered"] >= 5' 'd["still_max_error_mm"] <= 0.1' \
  'd["moving_max_error_per_speed_ms"] <= 150' 'all(f["status"] in (0, 1, 2) for f in d["fixes"])'
finish
