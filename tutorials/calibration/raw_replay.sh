# Localization from raw (distorted, tilted) images made ideal by the calibration, against
# the same drive's ideal images. A measurement, not a CI test (rendering raw frames takes
# minutes): run it from an empty folder with mosaicloc on the PATH; it prints each report's
# figures. The rows separate the two calibrations: the camera's (intrinsics and ground plane,
# which make the images ideal) with the camera's true place on the vehicle, then with its
# calibrated place too.
set -eu
# The vehicle of the simulated calibration drive (calibrate simulate-drive) drives the floor.
printf 'camera: {width_px: 560, height_px: 400, vehicle_from_camera: {x_mm: 212.5, y_mm: -14.0, yaw_rad: 0.035}}\nroute: {straight_length_m: 1.5}\n' > sim.yaml
mosaicloc --quiet simulate --out map-drive --config sim.yaml --route straight --laps 1 --speed-mps 0.5 --seed 21
mosaicloc --quiet map build --dataset map-drive --out floor.mosaic
mosaicloc --quiet simulate --out drive --config sim.yaml --route straight --laps 1 --speed-mps 1.0 --seed 22
mosaicloc --quiet replay --dataset drive --map floor.mosaic --out report-ideal
# The camera calibrated as in the tutorial: intrinsics, ground plane...
mosaicloc --quiet calibrate simulate --out captures
mosaicloc --quiet calibrate intrinsics --images 'captures/intrinsics/*.png' --board chessboard:9x6:20mm --out camera.xml
mosaicloc --quiet calibrate ground --images 'captures/ground/floor-0[1-4].png' --board chessboard:9x6:10mm --intrinsics camera.xml --mm-per-px 0.25 --width 560 --height 400 --out ground.yaml
# ... and its place on the vehicle, from a calibration drive seen raw and rectified.
mosaicloc --quiet calibrate simulate-drive --out cal-drive
mosaicloc --quiet calibrate simulate-raw --dataset cal-drive --out cal-drive-raw
mosaicloc --quiet calibrate rectify-dataset --dataset cal-drive-raw --ground ground.yaml --out cal-drive-rectified
mosaicloc --quiet calibrate vehicle --dataset cal-drive-rectified --out vehicle.yaml
# The drive and the map drive seen raw.
mosaicloc --quiet calibrate simulate-raw --dataset drive --config sim.yaml --out drive-raw
mosaicloc --quiet calibrate simulate-raw --dataset map-drive --config sim.yaml --out map-drive-raw
# Made ideal with the camera calibration, the datasets keeping the mounting the simulator
# drove with: what the rectification alone costs.
mosaicloc --quiet calibrate rectify-dataset --dataset drive-raw --ground ground.yaml --out drive-rectified-true-mounting
mosaicloc --quiet calibrate rectify-dataset --dataset map-drive-raw --ground ground.yaml --out map-drive-rectified-true-mounting
mosaicloc --quiet map build --dataset map-drive-rectified-true-mounting --out floor-rectified-true-mounting.mosaic
mosaicloc --quiet replay --dataset drive-rectified-true-mounting --map floor-rectified-true-mounting.mosaic --out report-raw-true-mounting
# With the calibrated mounting too, the map made the same way, as a calibrated mapping
# vehicle makes it: the whole installation.
mosaicloc --quiet calibrate rectify-dataset --dataset drive-raw --ground ground.yaml --vehicle vehicle.yaml --out drive-rectified
mosaicloc --quiet calibrate rectify-dataset --dataset map-drive-raw --ground ground.yaml --vehicle vehicle.yaml --out map-drive-rectified
mosaicloc --quiet map build --dataset map-drive-rectified --out floor-rectified.mosaic
mosaicloc --quiet replay --dataset drive-rectified --map floor-rectified.mosaic --out report-raw
# The raw drive against the ideal map, for comparison: the mounting error shows as an offset.
mosaicloc --quiet replay --dataset drive-rectified --map floor.mosaic --out report-raw-ideal-map
grep vehicle_from_camera: vehicle.yaml
for report in report-ideal report-raw-true-mounting report-raw report-raw-ideal-map; do
  python3 -c "import json,sys; m=json.load(open(sys.argv[1])); print(sys.argv[1], {k: m[k] for k in ('frames', 'fix_rate', 'lock_losses', 'position_rms_mm', 'position_max_mm', 'heading_rms_deg')})" "$report/metrics.json"
done
