# A site to try the link on: a mapped 2 m aisle and a run over it at 1 m/s.
printf 'route: {straight_length_m: 2.0}\n' > aisle.yaml
mosaicloc --quiet simulate --out aisle-map --config aisle.yaml --route straight --laps 1 --speed-mps 0.5 --seed 3
mosaicloc --quiet map build --dataset aisle-map --out aisle.mosaic
mosaicloc --quiet simulate --out aisle-run --config aisle.yaml --route straight --laps 1 --speed-mps 1.0 --seed 4
# The run configuration: the recording stands in for the camera, the PLC is on port 15020.
printf 'map: aisle.mosaic\ncamera: {source: dataset, dataset: {path: aisle-run}}\nplc: {port: 15020}\n' > run.yaml
# A start a moment ahead, for the PLC and the camera to play in step.
START=$(python3 -c 'import time; print(time.time() + 1.5)')
mosaicloc plc-sim --dataset aisle-run --port 15020 --start-unix "$START" --request-period-ms 500 --linger 4 > plc-sim.log &
mosaicloc run --config run.yaml --start-unix "$START" --record aisle-recorded
# While plc-sim lingers, read the last fix as the PLC holds it: x, y (0.01 mm), yaw (urad).
mbpoll -m tcp -a 1 -0 -1 -r 100 -c 3 -t 4:int -B -p 15020 127.0.0.1 | grep '^\['
# Status, quality, the request answered, heartbeat and the localizer's mode (1: track).
mbpoll -m tcp -a 1 -0 -1 -r 106 -c 5 -t 4 -p 15020 127.0.0.1 | grep '^\['
wait
tail -1 plc-sim.log
# Validate the recording offline.
mosaicloc --quiet replay --dataset aisle-recorded --map aisle.mosaic --out aisle-report
