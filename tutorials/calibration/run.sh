# 1. Print the board.
mosaicloc calibrate board --board chessboard:9x6:20mm --out board.png
# 2. Capture. Here: photographs through a simulated camera whose truth is known.
mosaicloc calibrate simulate --out captures
cat captures/truth.yaml
# 3. Calibrate the intrinsics.
mosaicloc calibrate intrinsics --images 'captures/intrinsics/*.png' --board chessboard:9x6:20mm --out camera.xml
# 4. Rectify: the ground plane from the board lying on the floor.
mosaicloc calibrate ground --images 'captures/ground/floor-0[1-4].png' --board chessboard:9x6:10mm --intrinsics camera.xml --mm-per-px 0.25 --width 560 --height 400 --out ground.yaml
mosaicloc calibrate rectify --ground ground.yaml --images 'captures/ground/*.png' --out-dir ideal
# 5. Mount: the camera's place on the vehicle from a calibration drive.
mosaicloc calibrate simulate-drive --out drive
mosaicloc --quiet calibrate vehicle --dataset drive --out vehicle.yaml
#    A tricycle's: a straight run, then a pivot with the steered wheel across.
mosaicloc calibrate simulate-drive --kind tricycle --out tug-drive
mosaicloc --quiet calibrate vehicle --dataset tug-drive --out tug.yaml
# 6. Verify: a photograph the calibration did not use, rectified and measured.
mosaicloc calibrate verify --ground ground.yaml --images 'captures/ground/floor-05.png' --board chessboard:9x6:10mm
# ViSP's own calibration photographs, where the visp-images-data package is installed.
grid=/usr/share/visp-images-data/ViSP-images/calibration
if [ -e "$grid/grid36-01.pgm" ]; then mosaicloc calibrate intrinsics --images "$grid/grid36-0*.pgm" --board circles:6x6:34mm --out grid36.xml; fi
