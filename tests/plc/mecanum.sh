# A mecanum vehicle live: `plc-sim` serves its four wheel counters (front left and right in
# registers 0-1 and 2-3, rear left and right in 8-9 and 10-11) while `run` renders the same
# drive's frames in real time; the vehicle crabs (faces up to 60 degrees off its path) as it
# goes. The run takes its kind from the drive, reads the four counters over Modbus and answers
# every fix request. Then the same drive recorded, its four counters served by an independent
# peer (Debian's pymodbus).
source "$(dirname "$0")/lib.sh"
TEXTURE="${MOSAICLOC_SHARED_DATA:-}/textures/asphalt_02_2048.jpg"
if [ ! -f "$TEXTURE" ]; then
  echo "shared data folder with real textures not found (MOSAICLOC_SHARED_DATA=${MOSAICLOC_SHARED_DATA:-unset}): skipped"
  exit 77
fi
cat > "$SCRATCH/drive.yaml" <<YAML
floor: {kind: image, image: $TEXTURE}
route: {name: straight, straight_length_m: 2.5, stop_s: 0.7, speed_mps: 1.0, crab_amplitude_deg: 60,
        crab_wavelength_m: 2.0}
vehicle: {kind: mecanum, mecanum_wheel_radius_mm: 76.0, track_width_mm: 560.0, wheelbase_mm: 480.0}
encoders: {mecanum_radius_error: 0.01, lateral_slip: 0.04}
run: {seed: 32, laps: 1}
YAML
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/map-run" --config "$SCRATCH/drive.yaml" --speed-mps 0.5 --seed 31 \
  >/dev/null || fail "simulate the mapping run"
"$MOSAICLOC" --quiet map build --dataset "$SCRATCH/map-run" --out "$SCRATCH/site.mosaic" --poses groundtruth >/dev/null || fail "map build"
PORT=$(free_port)
printf 'map: %s\ncamera: {source: simulator, simulator: {config: %s}}\nplc: {port: %s}\n' \
  "$SCRATCH/site.mosaic" "$SCRATCH/drive.yaml" "$PORT" > "$SCRATCH/run.yaml"
START=$(start_in 5.0)
"$MOSAICLOC" --json plc-sim --simulate "$SCRATCH/drive.yaml" --port "$PORT" --start-unix "$START" \
  --request-period-ms 200 >"$SCRATCH/plc.json" 2>"$SCRATCH/plc.err" &
PLC=$!
expect_exit 0 timeout 60 "$MOSAICLOC" --json run --config "$SCRATCH/run.yaml" --start-unix "$START"
cp "$SCRATCH/out" "$SCRATCH/run.jsonl"
wait $PLC || fail "plc-sim failed: $(tail -3 "$SCRATCH/plc.err")"
tail -1 "$SCRATCH/run.jsonl"
expect_in "$SCRATCH/plc.err" "serving the mecanum's front_left_ticks (registers 0-1), front_right_ticks (registers 2-3), rear_left_ticks (registers 8-9), rear_right_ticks (registers 10-11)"
json_check "$SCRATCH/run.jsonl" 'd["fix_rate"] >= 0.95' 'd["lock_losses"] == 0' 'd["answered"] >= 5' \
  'd["answered"] == d["requests"]' 'd["encoder_rejected"] == 0' 'd["encoder_samples"] >= 300' \
  'abs(d["wheel_scale_percent"]) < 10' 'abs(d["lateral_scale_percent"]) < 20' '"wheel_scale_left_percent" not in d'
json_check "$SCRATCH/plc.json" 'd["answered"] >= 5' 'd["fixes_received"] >= 20'

"$MOSAICLOC" --quiet simulate --out "$SCRATCH/run-ds" --config "$SCRATCH/drive.yaml" >/dev/null || fail "simulate the drive"
PORT=$(free_port)
printf 'map: %s\ncamera: {source: dataset, dataset: {path: %s}}\nplc: {port: %s}\n' \
  "$SCRATCH/site.mosaic" "$SCRATCH/run-ds" "$PORT" > "$SCRATCH/peer.yaml"
run_with_plc "$SCRATCH/peer.yaml" "$SCRATCH/run-ds" "$PORT"
json_check "$SCRATCH/run.jsonl" 'd["fix_rate"] >= 0.9' 'd["lock_losses"] == 0' 'd["answered"] == d["requests"]' \
  'd["encoder_rejected"] == 0' 'd["encoder_samples"] >= 300'
json_check "$SCRATCH/plc.json" 'd["answered"] >= 5' 'd["still_max_error_mm"] <= 0.1' \
  'all(f["status"] in (0, 1, 2) for f in d["fixes"])'
finish
