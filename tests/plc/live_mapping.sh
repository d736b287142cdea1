# Automatic mapping live (design.md sections 7d, 7e): `run --mapping` from an empty map plays a
# lap of a small loop on the procedural floor at 0.5 m/s in real time, with the pymodbus PLC serving its
# encoder counts, and maps it as it goes on a thread of its own. The map it leaves checks clean,
# its history holds the stretches, and a faster lap replayed on it tracks it.
source "$(dirname "$0")/lib.sh"
require_peers
printf 'route: {loop_width_m: 2.0, loop_height_m: 1.2, stop_s: 0.7}\n' > "$SCRATCH/site.yaml"
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/site-run" --config "$SCRATCH/site.yaml" --floor procedural \
  --route loop --laps 1 --speed-mps 0.5 --seed 71 >/dev/null || fail "simulate the mapping lap"
"$MOSAICLOC" --quiet simulate --out "$SCRATCH/later" --config "$SCRATCH/site.yaml" --floor procedural \
  --route loop --laps 1 --speed-mps 1.5 --seed 72 >/dev/null || fail "simulate the later lap"
PORT=$(free_port)
run_config "$SCRATCH/run.yaml" "$PORT"
run_with_plc "$SCRATCH/run.yaml" "$SCRATCH/site-run" "$PORT" --mapping
json_check "$SCRATCH/run.jsonl" 'd["map_extension_tiles"] > 50' 'd["map_extension_segments"] >= 2' \
  'd["map_extension_closed"] >= 1' 'd["map_keeping_dropped"] == 0' 'd["map_reindexed"]' 'd["lock_losses"] == 0'
expect_exit 0 "$MOSAICLOC" --quiet map check "$SCRATCH/site.mosaic"
expect_exit 0 "$MOSAICLOC" --quiet map history "$SCRATCH/site.mosaic"
expect_in "$SCRATCH/out" "automatic mapping"
expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/later" --map "$SCRATCH/site.mosaic" \
  --out "$SCRATCH/later-report" --revisit-places 0
# Against the truth the map is as good as its loop closure made it (the lap's drift spread over
# it): within 3 mm; against itself repeatable.
json_check "$SCRATCH/later-report/metrics.json" 'd["fix_rate"] >= 0.97' 'd["lock_losses"] == 0' 'd["position_max_mm"] < 3.0' \
  'd["repeatability_camera_mm"] <= 0.01'
finish
