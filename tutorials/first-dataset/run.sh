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
