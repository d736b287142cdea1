# The baseline pipeline: simulate, check, dead-reckon, evaluate. The report has every key.
source "$(dirname "$0")/lib.sh"
printf 'camera: {width_px: 160, height_px: 120}\nroute: {speed_mps: 2.0}\nrun: {laps: 1}\n' > "$SCRATCH/c.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/ds" --config "$SCRATCH/c.yaml" --route loop
expect_in "$SCRATCH/out" "(1.00 laps of 11.14 m)"
expect_exit 0 "$MOSAICLOC" --json dataset check "$SCRATCH/ds"
expect_in "$SCRATCH/out" '"valid": true'

expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/ds" --out "$SCRATCH/report" --mode dead-reckoning
for key in frames fixes fix_rate lock_losses position_rms_mm position_p50_mm position_p99_mm \
           position_max_mm heading_rms_deg heading_max_deg repeatability_mm processing_fps \
           latency_p50_ms latency_p99_ms max_speed_mps overlap_speed_limit_mps; do
  expect_in "$SCRATCH/report/metrics.json" "\"$key\":"
done
for file in estimate.tum fixes.csv metrics.json trajectory.png position_error.png heading_error.png; do
  [ -s "$SCRATCH/report/$file" ] || fail "report file $file missing or empty"
done
# Dead reckoning with a +0.3 % / +0.1 % wheel error drifts: measurable, but not absurd.
python3 - "$SCRATCH/report/metrics.json" <<'PY' || fail "dead-reckoning figures out of range"
import json, sys
m = json.load(open(sys.argv[1]))
assert m["fixes"] == 0 and m["fix_rate"] == 0, m
assert 1.0 < m["position_max_mm"] < 500.0, m["position_max_mm"]
assert 1.9 < m["max_speed_mps"] <= 2.01, m["max_speed_mps"]
assert abs(m["overlap_speed_limit_mps"] - 0.040 * 30 * 0.5) < 0.05, m["overlap_speed_limit_mps"]
PY

expect_exit 0 "$MOSAICLOC" --quiet evaluate --estimate "$SCRATCH/report/estimate.tum" \
  --groundtruth "$SCRATCH/ds/groundtruth/data.tum" --out "$SCRATCH/eval"
python3 - "$SCRATCH/report/metrics.json" "$SCRATCH/eval/metrics.json" <<'PY' || fail "evaluate disagrees with replay"
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:3])
# estimate.tum keeps nanometres: the figures agree to well under a micrometre.
assert abs(a["position_rms_mm"] - b["position_rms_mm"]) < 1e-4, (a, b)
assert b["processing_fps"] is None and b["fixes"] is None
PY
finish
