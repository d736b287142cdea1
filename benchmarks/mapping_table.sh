#!/usr/bin/env bash
# The mapping table: a site mapped from a mapping drive's frames and encoders alone, against
# the same site mapped from chained visual odometry and painted at the simulator's true poses,
# and drives localized on each map.
#  Each case is ROUTE:FLOOR: the network route at scale 1.0 (12 m x 6 m, 85 m: junctions, a
#  cross aisle, a spur driven both ways) or the serpentine survey, over procedural concrete,
#  asphalt or the (repeating) brick floor of ../shared/data. The mapping drive: one lap at
#  0.5 m/s, wheels 2 % and 2.5 % larger than calibrated, the simulator's slip. The maps:
#    truth  painted at the true poses (map build --poses groundtruth);
#    vo     painted at the chained visual odometry (replay --mode visual-odometry);
#    est    the poses estimated by map build (registration, loop closures, pose graph).
#  Map columns: the poses' error against the truth after the best rigid alignment (RMS, max),
#  the seams after optimization (RMS, max, px), loop closures accepted of those tried, the
#  wall time of the estimate and of the whole build against the drive's duration.
#  Drive columns: drives at 1.5 m/s and up to 7.2 m/s (3 m/s^2) over the same route with
#  other noise; fix rate, lock losses, wrong fixes (more than 1 mm from the truth, as the
#  replay counts them: the map's own frame error counts), the RMS against the truth, the RMS
#  after the best rigid alignment of the trajectory (the map's frame taken out), repeatability.
# Usage: benchmarks/mapping_table.sh [MOSAICLOC] [WORK_DIR] [CASES]
#        CASES default "network:procedural network:asphalt network:brick serpentine:procedural"
set -euo pipefail
HERE="$(cd "$(dirname "$0")/.." && pwd)"
MOSAICLOC=${1:-$HERE/build/release/app/mosaicloc}
WORK=${2:-$(mktemp -d)}
CASES=${3:-network:procedural network:asphalt network:brick serpentine:procedural}
source "$HERE/benchmarks/table_lib.sh"
mkdir -p "$WORK"

# config ROUTE SPEED ACCEL SEED WHEELS: a simulator.yaml
config() {
  local wheels=""
  [ "$5" = miscalibrated ] && wheels='encoders: {left_radius_error: 0.02, right_radius_error: 0.025}'
  printf 'route: {name: %s, network_scale: 1.0, speed_mps: %s, max_accel_mps2: %s}\nrun: {laps: 1, seed: %s}\n%s\n' \
    "$1" "$2" "$3" "$4" "$wheels"
}

printf '%-22s %-5s %9s %9s %8s %8s %9s %7s %7s | %-5s %8s %6s %6s %8s %8s %8s\n' case map err_rms err_max seam_rms \
  seam_max loops est_s build_s drive fix% losses wrong rms_mm aligned repeat
for case in $CASES; do
  table_case "$case" || continue
  D="$WORK/$route-$floor"
  mkdir -p "$D"
  config "$route" 0.5 1.0 81 miscalibrated > "$D/map.yaml"
  config "$route" 1.5 1.0 82 calibrated > "$D/d1.5.yaml"
  config "$route" 7.2 3.0 83 calibrated > "$D/d7.2.yaml"
  for run in map d1.5 d7.2; do
    [ -d "$D/$run" ] || "$MOSAICLOC" --quiet simulate --out "$D/$run" --config "$D/$run.yaml" --floor "$floor_arg" >/dev/null
  done
  duration=$("$PYTHON" -c "import sys; t=[int(l.split(',')[0]) for l in open(sys.argv[1]) if l[0].isdigit()]; print((t[-1]-t[0])/1e9)" \
    "$D/map/cam0/data.csv")
  # The three maps.
  rm -rf "$D/vo-replay" "$D/consistency"
  "$MOSAICLOC" --quiet replay --dataset "$D/map" --mode visual-odometry --out "$D/vo-replay" >/dev/null
  "$MOSAICLOC" --quiet map build --dataset "$D/map" --out "$D/truth.mosaic" --poses groundtruth --overwrite >/dev/null
  "$MOSAICLOC" --quiet map build --dataset "$D/map" --out "$D/vo.mosaic" --poses "$D/vo-replay/estimate.tum" \
    --overwrite >/dev/null
  start=$(date +%s.%N)
  "$MOSAICLOC" --quiet map poses --dataset "$D/map" --out "$D/est.tum" >/dev/null
  est_s=$("$PYTHON" -c "import sys,time; print(time.time() - float(sys.argv[1]))" "$start")
  start=$(date +%s.%N)
  "$MOSAICLOC" --quiet map build --dataset "$D/map" --out "$D/est.mosaic" --report "$D/consistency" --overwrite >/dev/null
  build_s=$("$PYTHON" -c "import sys,time; print(time.time() - float(sys.argv[1]))" "$start")
  for map in truth vo est; do
    case $map in
      truth) err="0 0"; seams="- -"; loops="-" ;;
      vo) err=$(aligned "$D/vo-replay/estimate.tum" "$D/map/groundtruth/data.tum"); seams="- -"; loops="-" ;;
      est)
        err=$(aligned "$D/est.tum" "$D/map/groundtruth/data.tum")
        read -r seam_rms seam_max loops < <("$PYTHON" -c "import json,sys; c=json.load(open(sys.argv[1])); \
print(f\"{c['seams']['after_rms_px']:.4f} {c['seams']['after_max_px']:.4f} {c['loops_accepted']}/{c['loops_tried']}\")" \
          "$D/consistency/consistency.json")
        seams="$seam_rms $seam_max"
        ;;
    esac
    for drive in d1.5 d7.2; do
      rep="$D/replay-$map-$drive"
      rm -rf "$rep"
      "$MOSAICLOC" --quiet replay --dataset "$D/$drive" --map "$D/$map.mosaic" --out "$rep" >/dev/null
      al=$(aligned "$rep/estimate.tum" "$D/$drive/groundtruth/data.tum" | cut -d' ' -f1)
      "$PYTHON" - "$case" "$map" "$err" "$seams" "$loops" "$est_s" "$build_s" "$duration" "$drive" "$rep" "$al" <<'PY'
import json, sys
case, m, err, seams, loops, est_s, build_s, duration, drive, rep, al = sys.argv[1:12]
j = json.load(open(rep + "/metrics.json"))
e = err.split(); s = seams.split()
times = f"{float(est_s):7.1f} {float(build_s):7.1f}" if m == "est" else f"{'-':>7} {'-':>7}"
g = lambda k, f: (f % j[k]) if j.get(k) is not None else "n/a"
print(f"{case:<22} {m:<5} {float(e[0]):9.4f} {float(e[1]):9.4f} {s[0]:>8} {s[1]:>8} {loops:>9} {times} | "
      f"{drive:<5} {100 * j['fix_rate']:8.3f} {g('lock_losses', '%6d')} {g('wrong_fixes', '%6d')} "
      f"{g('position_rms_mm', '%8.4f')} {float(al):8.4f} {g('repeatability_mm', '%8.4f')}")
PY
    done
  done
  echo "  ($case: mapping drive $duration s; est_s: map poses, build_s: map build with the estimate and painting)"
done
