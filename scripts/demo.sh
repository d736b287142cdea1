#!/usr/bin/env bash
# The main job on the embedded default: simulate an AGV driving laps of a loop over a
# procedural concrete floor, localize it, and report against the ground truth.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh

BUILD=build/release
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Release -DMOSAICLOC_BUILD_TESTS=OFF \
  -DMOSAICLOC_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$BUILD" --target mosaicloc -j "$(nproc)"
MOSAICLOC="$BUILD/app/mosaicloc"

OUT=out/demo
mkdir -p "$OUT"
echo
echo "== simulate: 3 laps of a 4 m x 2 m loop at 1.5 m/s over a procedural floor"
"$MOSAICLOC" simulate --out "$OUT/dataset" --overwrite --route loop --laps 3 --speed-mps 1.5 --seed 1
echo
echo "== replay: dead reckoning from the wheel encoders (the drift a mosaic fix removes)"
rm -rf "$OUT/report"
"$MOSAICLOC" replay --dataset "$OUT/dataset" --out "$OUT/report" --mode dead-reckoning
echo
echo "== map: paint the frames at their true poses into a mosaic, and export it to look at"
"$MOSAICLOC" map build --dataset "$OUT/dataset" --out "$OUT/floor.mosaic" --overwrite
"$MOSAICLOC" map export "$OUT/floor.mosaic" --out "$OUT/report/map.png" --level 2
echo
echo "Report: $(pwd)/$OUT/report (metrics.json, estimate.tum, fixes.csv, trajectory.png,"
echo "        position_error.png, heading_error.png, map.png); map: $(pwd)/$OUT/floor.mosaic"
