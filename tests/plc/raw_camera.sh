# The live run on a real camera: a drive recorded raw (distorted and tilted, as the camera
# sees it) is played as the camera, every frame is rectified with the ground calibration made
# from simulated photographs, localized on the map, and the fixes sent to a pymodbus PLC.
source "$(dirname "$0")/lib.sh"
require_peers
TEXTURE="${MOSAICLOC_SHARED_DATA:-}/textures/asphalt_02_2048.jpg"
if [ ! -f "$TEXTURE" ]; then
  echo "shared data folder with real textures not found (MOSAICLOC_SHARED_DATA=${MOSAICLOC_SHARED_DATA:-unset}): skipped"
  exit 77
fi
# The camera calibrated as in tutorials/calibration: intrinsics, then the ground plane, for
# 560x400 ideal images at 0.25 mm/px.
"$MOSAICLOC" --quiet calibrate simulate --out "$SCRATCH/captures" >/dev/null || fail "calibrate simulate"
"$MOSAICLOC" --quiet calibrate intrinsics --images "$SCRATCH/captures/intrinsics/*.png" --board chessboard:9x6:20mm \
  --out "$SCRATCH/camera.xml" >/dev/null || fail "calibrate intrinsics"
"$MOSAICLOC" --quiet calibrate ground --images "$SCRATCH/captures/ground/floor-0[1-4].png" --board chessboard:9x6:10mm \
  --intrinsics "$SCRATCH/camera.xml" --mm-per-px 0.25 --width 560 --height 400 --out "$SCRATCH/ground.yaml" \
  >/dev/null || fail "calibrate ground"
# The site mapped with ideal images, and a drive over it seen by the raw camera.
printf 'floor: {kind: image, image: %s}\ncamera: {width_px: 560, height_px: 400}\nroute: {name: straight, straight_length_m: 1.2, stop_s: 0.7}\n' \
  "$TEXTURE" > "$SCRATCH/site.yaml"
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/map-run" --config "$SCRATCH/site.yaml" --laps 1 --speed-mps 0.5 \
  --seed 31 >/dev/null || fail "simulate the mapping run"
"$MOSAICLOC" --quiet map build --dataset "$SCRATCH/map-run" --out "$SCRATCH/site.mosaic" --poses groundtruth >/dev/null || fail "map build"
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/run" --config "$SCRATCH/site.yaml" --laps 1 --speed-mps 1.0 \
  --seed 32 >/dev/null || fail "simulate the drive"
"$MOSAICLOC" --quiet calibrate simulate-raw --dataset "$SCRATCH/run" --config "$SCRATCH/site.yaml" \
  --out "$SCRATCH/run-raw" >/dev/null || fail "calibrate simulate-raw"

PORT=$(free_port)
cat > "$SCRATCH/run.yaml" <<YAML
map: $SCRATCH/site.mosaic
camera:
  source: dataset
  dataset: {path: $SCRATCH/run-raw}
  ground: $SCRATCH/ground.yaml
plc: {port: $PORT, response_timeout_ms: 30, heartbeat_timeout_ms: 300}
YAML
run_with_plc "$SCRATCH/run.yaml" "$SCRATCH/run-raw" "$PORT" --record "$SCRATCH/rec"
json_check "$SCRATCH/run.jsonl" 'd["fix_rate"] >= 0.95' 'd["lock_losses"] == 0' 'd["answered"] == d["requests"]' \
  'd["requests"] >= 5'
# What it recorded is the rectified, ideal image. The fixes hold the lock as from an ideal
# camera; against the truth they carry the calibration's small error in where the camera
# floor frame is (about 0.08 mm here), which on a vehicle `calibrate vehicle` measures into
# vehicle_from_camera for the mapping run and the drive alike (tutorials/calibration).
expect_in "$SCRATCH/rec/dataset.yaml" "width_px: 560"
check_recorded_fixes "$SCRATCH/rec" "$SCRATCH/run-raw" 0.15
json_check "$SCRATCH/plc.json" 'd["still_fixes"] >= 3' 'd["still_max_error_mm"] <= 0.1'

# A raw recording of another size than the calibration's raw image is refused, naming both.
"$MOSAICLOC" --quiet calibrate rectify-dataset --dataset "$SCRATCH/run-raw" --ground "$SCRATCH/ground.yaml" \
  --out "$SCRATCH/run-ideal" >/dev/null || fail "calibrate rectify-dataset"
sed "s|$SCRATCH/run-raw|$SCRATCH/run-ideal|" "$SCRATCH/run.yaml" > "$SCRATCH/wrong.yaml"
expect_exit 1 timeout 30 "$MOSAICLOC" --quiet run --config "$SCRATCH/wrong.yaml"
expect_in "$SCRATCH/err" "frame (type 0) where the ground calibration expects"
finish
