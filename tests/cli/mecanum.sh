# A mecanum vehicle: its dataset names its kind and four counters; it crabs (faces up to 60
# degrees off its path) and turns; a map painted from its slow lap localizes a faster drive
# whose wheels are 2 % larger than calibrated and whose rollers slip 5 % sideways, and the
# filter learns both scales. Sideways motion asked of another kind, and a calibration drive of
# a mecanum vehicle, are refused with the reason.
source "$(dirname "$0")/lib.sh"
vehicle='vehicle: {kind: mecanum, mecanum_wheel_radius_mm: 76.0, track_width_mm: 560.0, wheelbase_mm: 480.0, ticks_per_revolution: 4096}'
route='route: {loop_width_m: 2.4, loop_height_m: 1.6, corner_radius_m: 0.6, crab_amplitude_deg: 60, crab_wavelength_m: 3}'
printf '%s\n%s\n' "$route" "$vehicle" > "$SCRATCH/map.yaml"
printf '%s\n%s\nencoders: {mecanum_radius_error: 0.02, lateral_slip: 0.05}\n' "$route" "$vehicle" > "$SCRATCH/drive.yaml"

expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/map-ds" --config "$SCRATCH/map.yaml" --route loop --laps 1 \
  --speed-mps 0.5 --seed 3
expect_in "$SCRATCH/map-ds/dataset.yaml" "kind: mecanum"
expect_in "$SCRATCH/map-ds/encoders/data.csv" "#timestamp_ns,front_left_ticks,front_right_ticks,rear_left_ticks,rear_right_ticks"
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/map-ds" --out "$SCRATCH/site.mosaic" --poses groundtruth
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/drive" --config "$SCRATCH/drive.yaml" --route loop --laps 1 \
  --speed-mps 1.5 --seed 4
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/site.mosaic" \
  --out "$SCRATCH/report"
json_check "$SCRATCH/report/metrics.json" 'd["fix_rate"] >= 0.99' 'd["lock_losses"] == 0' 'd["wrong_fixes"] == 0' \
  'd["position_max_mm"] < 0.1' 'abs(d["wheel_scale_percent"] - 2.0) < 0.3' \
  'abs(d["lateral_scale_percent"] + 5.0) < 0.5' '"wheel_scale_left_percent" not in d'
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --mode dead-reckoning --out "$SCRATCH/dr"
json_check "$SCRATCH/dr/metrics.json" 'd["position_max_mm"] > 20.0'

# Refused, with the reason.
printf '%s\n' "$route" > "$SCRATCH/crab.yaml"
expect_exit 2 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/x" --config "$SCRATCH/crab.yaml"
expect_in "$SCRATCH/err" "route.crab_amplitude_deg must be 0 for a differential (only a mecanum vehicle moves sideways)"
printf 'vehicle: {kind: mecanum, steering_offset_deg: 0.5}\n' > "$SCRATCH/mixed.yaml"
expect_exit 2 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/x" --config "$SCRATCH/mixed.yaml"
expect_in "$SCRATCH/err" "steering_offset_deg"
[ ! -e "$SCRATCH/x" ] || fail "a refused simulation left a dataset"
expect_exit 2 "$MOSAICLOC" --quiet calibrate vehicle --dataset "$SCRATCH/drive" --out "$SCRATCH/vehicle.yaml"
expect_in "$SCRATCH/err" "a mecanum vehicle has no calibration drive"
[ ! -e "$SCRATCH/vehicle.yaml" ] || fail "a refused calibration wrote a file"
expect_exit 2 "$MOSAICLOC" --quiet calibrate simulate-drive --kind mecanum --out "$SCRATCH/cal"
expect_in "$SCRATCH/err" "none for a mecanum vehicle"
finish
