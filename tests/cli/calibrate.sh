# The calibration steps as an integrator runs them, on simulated photographs whose truth
# is known: intrinsics (ViSP beside OpenCV), ground plane, verification, the camera's
# place on the vehicle; and the refusals of bad input, with nothing written.
source "$(dirname "$0")/lib.sh"

# json FILE EXPRESSION: evaluates a Python expression over the JSON document `d`.
json() { python3 -c "import json,sys; d=json.load(open(sys.argv[1])); print($2)" "$1"; }
# check_lt VALUE BOUND WHAT
check_lt() { python3 -c "import sys; sys.exit(0 if abs(float('$1')) < float('$2') else 1)" || fail "$3: |$1| >= $2"; }

expect_exit 0 "$MOSAICLOC" --quiet calibrate simulate --out "$SCRATCH/cal"
expect_exit 0 "$MOSAICLOC" --json calibrate intrinsics --images "$SCRATCH/cal/intrinsics/*.png" \
  --board chessboard:9x6:20mm --out "$SCRATCH/camera.xml"
cp "$SCRATCH/out" "$SCRATCH/intrinsics.json"
expect_in "$SCRATCH/camera.xml" "<type>perspectiveProjWithDistortion</type>"
# Truth: fx 812, fy 806, cx 326.4, cy 233.7, k1 -0.14 (calibrate simulate writes it to truth.yaml).
check_lt "$(json "$SCRATCH/intrinsics.json" "d['visp']['fx_px'] / 812.0 - 1")" 0.002 "ViSP fx"
check_lt "$(json "$SCRATCH/intrinsics.json" "d['visp']['fy_px'] / 806.0 - 1")" 0.002 "ViSP fy"
check_lt "$(json "$SCRATCH/intrinsics.json" "d['visp']['cx_px'] / 326.4 - 1")" 0.002 "ViSP cx"
check_lt "$(json "$SCRATCH/intrinsics.json" "d['visp']['cy_px'] / 233.7 - 1")" 0.002 "ViSP cy"
check_lt "$(json "$SCRATCH/intrinsics.json" "d['visp']['kud'] / -0.14 - 1")" 0.02 "ViSP kud"
check_lt "$(json "$SCRATCH/intrinsics.json" "d['opencv']['fx_px'] / 812.0 - 1")" 0.002 "OpenCV fx"
check_lt "$(json "$SCRATCH/intrinsics.json" "d['opencv']['kud'] / -0.14 - 1")" 0.02 "OpenCV k1"
[ "$(json "$SCRATCH/intrinsics.json" "len(d['images'])")" = 12 ] || fail "not every image reported"

# Calibrating again replaces the camera XML (vpXmlParserCamera alone refuses a second camera of that name).
expect_exit 0 "$MOSAICLOC" --quiet calibrate intrinsics --images "$SCRATCH/cal/intrinsics/board-0[1-5].png" \
  --board chessboard:9x6:20mm --out "$SCRATCH/camera.xml"
expect_in "$SCRATCH/out" "ViSP"
expect_in "$SCRATCH/out" "OpenCV"

expect_exit 0 "$MOSAICLOC" --json calibrate ground --images "$SCRATCH/cal/ground/floor-0[1-4].png" \
  --board chessboard:9x6:10mm --intrinsics "$SCRATCH/camera.xml" --mm-per-px 0.25 --width 560 --height 400 \
  --out "$SCRATCH/ground.yaml"
cp "$SCRATCH/out" "$SCRATCH/ground.json"
check_lt "$(json "$SCRATCH/ground.json" "d['height_mm'] - 200.0")" 0.5 "camera height"
check_lt "$(json "$SCRATCH/ground.json" "1 - d['coverage']")" 1e-9 "ideal image inside the raw one"
expect_exit 0 "$MOSAICLOC" --json calibrate verify --ground "$SCRATCH/ground.yaml" \
  --images "$SCRATCH/cal/ground/floor-05.png" --board chessboard:9x6:10mm
check_lt "$(json "$SCRATCH/out" "d['worst_scale_error_percent']")" 0.1 "rectified scale error, percent"
expect_exit 0 "$MOSAICLOC" --quiet calibrate rectify --ground "$SCRATCH/ground.yaml" \
  --images "$SCRATCH/cal/ground/*.png" --out-dir "$SCRATCH/ideal"
[ "$(ls "$SCRATCH/ideal" | wc -l)" = 5 ] || fail "rectify did not write five images"

expect_exit 0 "$MOSAICLOC" --quiet calibrate simulate-drive --out "$SCRATCH/drive"
expect_exit 0 "$MOSAICLOC" --quiet --json calibrate vehicle --dataset "$SCRATCH/drive" --out "$SCRATCH/vehicle.yaml"
cp "$SCRATCH/out" "$SCRATCH/vehicle.json"
check_lt "$(json "$SCRATCH/vehicle.json" "d['x_mm']['error']")" 0.5 "vehicle_from_camera x"
check_lt "$(json "$SCRATCH/vehicle.json" "d['y_mm']['error']")" 0.5 "vehicle_from_camera y"
check_lt "$(json "$SCRATCH/vehicle.json" "d['yaw_deg']['error']")" 0.05 "vehicle_from_camera yaw"
check_lt "$(json "$SCRATCH/vehicle.json" "d['track_width_mm']['error']")" 1.0 "track width"
expect_in "$SCRATCH/vehicle.yaml" "vehicle_from_camera_sigma:"

# ViSP's own photographs of its circle grid, where the package is installed.
GRID=/usr/share/visp-images-data/ViSP-images/calibration
if [ -e "$GRID/grid36-01.pgm" ]; then
  expect_exit 0 "$MOSAICLOC" calibrate intrinsics --images "$GRID/grid36-0*.pgm" --board circles:6x6:34mm \
    --out "$SCRATCH/grid36.xml"
  expect_in "$SCRATCH/out" "4 of 4 images used"
else
  echo "skipping the grid36 check: $GRID is absent (install visp-images-data)"
fi

# Bad input: exit 2, one line naming what is wrong, nothing written.
expect_exit 2 "$MOSAICLOC" calibrate intrinsics --images "$SCRATCH/nothing-here/*.png" --board chessboard:9x6:20mm \
  --out "$SCRATCH/bad.xml"
expect_in "$SCRATCH/err" "no images match"
expect_exit 2 "$MOSAICLOC" calibrate intrinsics --images "$SCRATCH/cal/intrinsics/*.png" --board chessboard:9x6 \
  --out "$SCRATCH/bad.xml"
expect_in "$SCRATCH/err" "bad board 'chessboard:9x6'"
expect_exit 0 "$MOSAICLOC" --quiet calibrate board --board circles:4x3:20mm --px-per-mm 4 --out "$SCRATCH/circles.png"
expect_exit 2 "$MOSAICLOC" calibrate intrinsics --images "$SCRATCH/circles.png" --board chessboard:9x6:20mm \
  --out "$SCRATCH/bad.xml"
expect_in "$SCRATCH/err" "not found in any of the 1 images"
echo "not an image" > "$SCRATCH/broken.png"
expect_exit 2 "$MOSAICLOC" calibrate intrinsics --images "$SCRATCH/broken.png" --board chessboard:9x6:20mm \
  --out "$SCRATCH/bad.xml"
expect_in "$SCRATCH/err" "broken.png: cannot be read as an image"
expect_exit 2 "$MOSAICLOC" calibrate ground --images "$SCRATCH/cal/ground/*.png" --board chessboard:9x6:10mm \
  --intrinsics "$SCRATCH/no-camera.xml" --out "$SCRATCH/bad.yaml"
expect_in "$SCRATCH/err" "no-camera.xml"
[ "$(wc -l < "$SCRATCH/err")" = 1 ] || fail "the error is not one line: $(cat "$SCRATCH/err")"
expect_exit 2 "$MOSAICLOC" calibrate vehicle --dataset "$SCRATCH/no-drive"
[ ! -e "$SCRATCH/bad.xml" ] && [ ! -e "$SCRATCH/bad.yaml" ] || fail "a failed calibration wrote its output"
[ -z "$(ls -A "$SCRATCH" | grep '^\.')" ] || fail "temporary files left: $(ls -A "$SCRATCH")"

finish
