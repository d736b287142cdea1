# mosaicloc limits: the speed limits of a setup, the shipped configuration equal to the
# defaults, a setup changed in YAML, and bad configurations named by file, line and key.
source "$(dirname "$0")/lib.sh"
CONFIG="$MOSAICLOC_SOURCE_DIR/config/default/limits.yaml"

expect_exit 0 "$MOSAICLOC" limits
expect_in "$SCRATCH/out" "overlap speed limit"
expect_in "$SCRATCH/out" "instability ratio S / Lambda = 1.500"
cat "$SCRATCH/out"

# The shipped file states the compiled defaults.
expect_exit 0 "$MOSAICLOC" --json limits
cp "$SCRATCH/out" "$SCRATCH/defaults.json"
expect_exit 0 "$MOSAICLOC" --json limits --config "$CONFIG"
cmp -s "$SCRATCH/out" "$SCRATCH/defaults.json" || fail "config/default/limits.yaml differs from the defaults"

# json_near FILE KEY VALUE: the key's value is VALUE within 1e-9 relative.
json_near() {
  python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); v=d[sys.argv[2]]; w=float(sys.argv[3]);
assert abs(v - w) <= 1e-9 * max(1.0, abs(w)), (sys.argv[2], v, w)' "$@" || fail "$2 is not $3 in $(cat "$1")"
}
json_near "$SCRATCH/defaults.json" overlap_speed_limit_mps 2.4
json_near "$SCRATCH/defaults.json" distortion_speed_limit_mps 3.75
json_near "$SCRATCH/defaults.json" blur_speed_limit_mps 7.5
json_near "$SCRATCH/defaults.json" prediction_speed_limit_mps 36
json_near "$SCRATCH/defaults.json" instability_ratio 1.5
# At 1 m/s frame-to-frame registration is beyond its limits (S / Lambda = 1.5), the mosaic not.
python3 -c 'import json,sys; d=json.load(open(sys.argv[1]));
assert d["frame_to_frame_holds"] is False and d["mosaic_holds"] is True' "$SCRATCH/defaults.json" ||
  fail "the verdicts at 1 m/s are wrong in $(cat "$SCRATCH/defaults.json")"

# A faster camera mounted across the vehicle: the footprint along the travel is the image
# height (120 mm), so at 60 Hz the overlap limit is 120 mm x 0.5 x 60 Hz = 3.6 m/s.
cat >"$SCRATCH/across.yaml" <<YAML
camera:
  frame_rate_hz: 60.0
  vehicle_from_camera_yaw_rad: 1.5707963267948966
speed_mps: 3.6
YAML
expect_exit 0 "$MOSAICLOC" --json limits --config "$SCRATCH/across.yaml"
json_near "$SCRATCH/out" overlap_speed_limit_mps 3.6
json_near "$SCRATCH/out" instability_ratio 0.5
expect_exit 0 "$MOSAICLOC" --json limits --config "$SCRATCH/across.yaml" --speed-mps 1.8
json_near "$SCRATCH/out" instability_ratio 0.25

# Joints 2 mm deep: the relief's terms (0.5 px x 0.25 mm x 202 mm / (2 mm / 30 Hz) = 0.37875 m/s).
printf 'floor: {relief_depth_mm: 2.0}\n' >"$SCRATCH/relief.yaml"
expect_exit 0 "$MOSAICLOC" --json limits --config "$SCRATCH/relief.yaml"
json_near "$SCRATCH/out" relief_distortion_speed_limit_mps 0.37875
json_near "$SCRATCH/out" relief_shadow_mm 0.5
expect_exit 0 "$MOSAICLOC" limits --config "$SCRATCH/relief.yaml"
expect_in "$SCRATCH/out" "parallax at the image corner"

# Bad configurations: every problem at once, with file, line and key.
cat >"$SCRATCH/bad.yaml" <<YAML
camera:
  frame_rate: 30
floor:
  depth_gradient: -1
YAML
expect_exit 2 "$MOSAICLOC" limits --config "$SCRATCH/bad.yaml"
expect_in "$SCRATCH/err" "bad.yaml:2: camera.frame_rate: unknown key"
expect_in "$SCRATCH/err" "bad.yaml:4: floor.depth_gradient"
expect_exit 2 "$MOSAICLOC" limits --config "$SCRATCH/missing.yaml"
expect_exit 2 "$MOSAICLOC" limits --speed-mps -1
finish
