# Simulate a vehicle driving two laps of a loop over a procedural concrete floor.
mosaicloc simulate --out loop-dataset --route loop --laps 2 --speed-mps 1.5 --seed 7
# Read back every file and line of it.
mosaicloc dataset check loop-dataset
# Dead-reckon from the wheel encoders alone and compare with the ground truth.
mosaicloc replay --dataset loop-dataset --out loop-report --mode dead-reckoning
ls loop-report
# Paint the frames at their true poses into a mosaic map and look at it.
mosaicloc map build --dataset loop-dataset --out loop.mosaic
mosaicloc map info loop.mosaic
mosaicloc map export loop.mosaic --out loop-map.png --level 2
# Localize against the map; then the same drive without its ground truth, as a real recording.
mosaicloc replay --dataset loop-dataset --map loop.mosaic --out map-report
mkdir -p recording
cp -r loop-dataset/cam0 loop-dataset/encoders loop-dataset/dataset.yaml recording/
mosaicloc replay --dataset recording --map loop.mosaic --out recording-report
mosaicloc report compare map-report recording-report --top 3
