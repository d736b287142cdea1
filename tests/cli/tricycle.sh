# A tricycle (tug, forklift): its dataset names its kind and counters, a map painted from its
# slow lap localizes a faster drive whose drive wheel is 2 % larger and whose steering is 0.5
# degrees off the calibration, and the filter learns both. A tricycle asked for with bends it
# cannot steer into, or with a differential drive's keys, is refused at the key.
source "$(dirname "$0")/lib.sh"
vehicle='vehicle: {kind: tricycle, drive_wheel_radius_mm: 100.0, wheelbase_mm: 1200.0, ticks_per_revolution: 4096, steering_ticks_per_revolution: 65536}'
route='route: {loop_width_m: 2.4, loop_height_m: 1.6, corner_radius_m: 0.6, curvature_transition_m: 0.4}'
printf '%s\n%s\n' "$route" "$vehicle" > "$SCRATCH/map.yaml"
printf '%s\n%s\nencoders: {drive_radius_error: 0.02, steering_offset_error_deg: 0.5}\n' "$route" "$vehicle" \
  > "$SCRATCH/drive.yaml"

expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/map-ds" --config "$SCRATCH/map.yaml" --route loop --laps 1 \
  --speed-mps 0.5 --seed 3
expect_in "$SCRATCH/map-ds/dataset.yaml" "kind: tricycle"
expect_in "$SCRATCH/map-ds/encoders/data.csv" "#timestamp_ns,drive_ticks,steering_ticks"
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/map-ds" --out "$SCRATCH/site.mosaic" --poses groundtruth
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/drive" --config "$SCRATCH/drive.yaml" --route loop --laps 1 \
  --speed-mps 1.5 --seed 4
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/site.mosaic" \
  --out "$SCRATCH/report"
json_check "$SCRATCH/report/metrics.json" 'd["fix_rate"] >= 0.99' 'd["lock_losses"] == 0' 'd["wrong_fixes"] == 0' \
  'd["position_max_mm"] < 0.5' 'abs(d["drive_wheel_scale_percent"] - 2.0) < 0.2' \
  'abs(d["steering_offset_error_deg"] - 0.5) < 0.1' '"wheel_scale_left_percent" not in d'
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --mode dead-reckoning --out "$SCRATCH/dr"
json_check "$SCRATCH/dr/metrics.json" 'd["position_max_mm"] > 20.0'

# Refused, at the key.
printf 'route: {curvature_transition_m: 0.0}\n%s\n' "$vehicle" > "$SCRATCH/sharp.yaml"
expect_exit 2 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/x" --config "$SCRATCH/sharp.yaml"
expect_in "$SCRATCH/err" "route.curvature_transition_m must be > 0 for a tricycle"
printf 'vehicle: {kind: tricycle, track_width_mm: 500.0}\n' > "$SCRATCH/mixed.yaml"
expect_exit 2 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/x" --config "$SCRATCH/mixed.yaml"
expect_in "$SCRATCH/err" "track_width_mm"
[ ! -e "$SCRATCH/x" ] || fail "a refused simulation left a dataset"

# Calibration: the drive wheel's radius, the wheelbase and the steering zero from a straight
# run and a pivot with the steered wheel across; the file holds the tricycle's keys.
expect_exit 0 "$MOSAICLOC" --quiet calibrate simulate-drive --kind tricycle --out "$SCRATCH/cal"
expect_exit 0 "$MOSAICLOC" --quiet --json calibrate vehicle --dataset "$SCRATCH/cal" --out "$SCRATCH/vehicle.yaml"
cp "$SCRATCH/out" "$SCRATCH/vehicle.json"
json_check "$SCRATCH/vehicle.json" 'd["kind"] == "tricycle"' 'abs(d["steering_offset_deg"]["error"]) < 0.05' \
  'abs(d["wheelbase_mm"]["error"]) < 0.5' 'abs(d["drive_wheel_radius_mm"]["error"]) < 0.1' \
  'abs(d["y_mm"]["error"]) < 0.5' 'abs(d["yaw_deg"]["error"]) < 0.05' 'd["steering_offset_deg"]["sigma"] < 0.05'
expect_in "$SCRATCH/vehicle.yaml" "kind: tricycle"
expect_in "$SCRATCH/vehicle.yaml" "steering_offset_deg:"
finish
