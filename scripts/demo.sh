#!/usr/bin/env bash
# The main job on the embedded default: map a site's floor with one slow lap (the poses from
# the frames and encoders alone, as on a real site), drive faster laps over it, localize them
# against the mosaic, and report against the ground truth.
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
echo "== map the site: one slow lap of a 4 m x 2 m loop over a procedural concrete floor (0.5 m/s,"
echo "   well inside the overlap speed limit). The poses come from the frames and the encoders alone:"
echo "   frames registered to one another, the loop closed where the lap comes back to its start,"
echo "   a pose graph solved; the mosaic is painted at them (the ground truth only scores them)"
"$MOSAICLOC" simulate --out "$OUT/mapping" --overwrite --route loop --laps 1 --speed-mps 0.5 --seed 1
rm -rf "$OUT/consistency"
"$MOSAICLOC" map build --dataset "$OUT/mapping" --out "$OUT/floor.mosaic" --overwrite --report "$OUT/consistency"
echo
echo "== drive: 3 faster laps over the same floor (1.5 m/s, other sensor noise and wheel slip)"
"$MOSAICLOC" simulate --out "$OUT/dataset" --overwrite --route loop --laps 3 --speed-mps 1.5 --seed 2
echo
echo "== replay, dead reckoning only: the drift the mosaic removes"
rm -rf "$OUT/dead-reckoning" "$OUT/report"
"$MOSAICLOC" replay --dataset "$OUT/dataset" --out "$OUT/dead-reckoning" --mode dead-reckoning
echo
echo "== replay, localized against the self-built mosaic"
"$MOSAICLOC" replay --dataset "$OUT/dataset" --map "$OUT/floor.mosaic" --out "$OUT/report"
"$MOSAICLOC" map export "$OUT/floor.mosaic" --out "$OUT/report/map.png" --level 2
echo
echo "== result"
/usr/bin/python3 - "$OUT/report/metrics.json" "$OUT/dead-reckoning/metrics.json" "$OUT/consistency/consistency.json" <<'PY'
import json, sys
m, d, c = (json.load(open(f)) for f in sys.argv[1:4])
e = c["vs_groundtruth"]
print(f"map built from the mapping drive's frames and encoders: {c['loops_accepted']} loop closures, seams "
      f"{c['seams']['after_rms_px']:.4f} px RMS, poses {e['rms_mm']:.3f} mm RMS from the truth (best rigid alignment)")
print(f"localized on it:  {100 * m['fix_rate']:.1f} % of {m['frames']} frames fixed, {m['wrong_fixes']} wrong, "
      f"{m['lock_losses']} lock losses, {m['position_rms_mm']:.3f} mm RMS, repeatability {m['repeatability_mm']:.4f} mm")
print(f"from the drive alone (no truth): repeatability {m['revisit_repeatability_mm']:.4f} mm at the camera from "
      f"{m['revisit_places']} revisited places (the truth says {m['repeatability_camera_mm']:.4f} mm), "
      f"{100 * m['nis_inside_95_share']:.1f} % of fixes inside the filter's 95 % bound")
print(f"dead reckoning:   {d['position_rms_mm']:.1f} mm RMS, {d['final_position_error_mm']:.1f} mm off after "
      f"{d['path_length_m']:.0f} m ({d['drift_percent']:.2f} % of the path)")
PY
echo
echo "Report: $(pwd)/$OUT/report/index.html (the page to share; beside it metrics.json, estimate.tum,"
echo "        fixes.csv, map_state.png, map_quality.png, map_mode.png, timelines.png, trajectory.png,"
echo "        position_error.png, heading_error.png, map.png); dead reckoning: $(pwd)/$OUT/dead-reckoning;"
echo "        the map's consistency: $(pwd)/$OUT/consistency (consistency.json, loops.csv, seams.csv, path.csv, view.csv, residuals.png)"
