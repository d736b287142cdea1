# The soak (design.md section 8), short: a 1.6 x 1.2 m loop mapped at 0.5 m/s, then driven at
# 1 m/s for 600 frames in one process, the frames rendered as they are needed (a segment of
# four laps, then the next), 5 % of them dropped. Every fix within 1 mm of the truth, no lock
# lost, and the process holds no more descriptors or threads at the end than at the start.
# SIGTERM ends a drive early with its figures so far.
# Usage: soak.sh MOSAICLOC
source "$(dirname "$0")/lib.sh"
printf 'route: {loop_width_m: 1.6, loop_height_m: 1.2, corner_radius_m: 0.4}\ncamera: {drop_probability: 0.05}\n' \
  > "$SCRATCH/drive.yaml"
printf 'map: {cache_budget_mib: 16}\n' > "$SCRATCH/localizer.yaml"  # less than the lap's tiles take
expect_exit 0 "$MOSAICLOC" --quiet --json bench soak --frames 600 --route loop --speed-mps 1.0 \
  --config "$SCRATCH/drive.yaml" --localizer "$SCRATCH/localizer.yaml" --work "$SCRATCH/work"
python3 - "$SCRATCH/out" <<'PY' || fail "soak"
import json, sys
d = json.load(open(sys.argv[1]))
print({k: d[k] for k in ("frames", "fix_rate", "lock_losses", "wrong_fixes", "error_max_mm", "processing_p99_ms",
                         "driven_s", "rss_slope_mib_per_h")})
assert d["frames"] == 600 and d["wrong_fixes"] == 0 and d["lock_losses"] == 0, d
assert d["fix_rate"] >= 0.95 and d["error_max_mm"] <= 0.1, d
assert d["driven_s"] > 600 / 30.0 and d["driven_km"] > 0.015, d  # the drops: more drive than frames; two segments
col = {name: i for i, name in enumerate(d["samples_columns"])}
first, last = d["samples"][0], d["samples"][-1]
assert last[col["frames"]] == 600 and len(d["samples"]) >= 2, d["samples"]
assert last[col["fds"]] <= first[col["fds"]] + 1, (first, last)  # descriptors: the map's
assert last[col["threads"]] == first[col["threads"]], (first, last)
# The map's decoded tiles fill the cache's budget and stay within it (plus the one slab of 64
# tiles of 256 x 256 px a miss may add); the heap is sampled (near 0 under AddressSanitizer).
cache = [s[col["cache_mib"]] for s in d["samples"]]
print("map cache MiB:", cache[0], "->", max(cache))
assert 12 <= max(cache) <= 16 + 4, cache
assert all(s[col["heap_mib"]] >= 0 for s in d["samples"]), d["samples"]
PY
[ -f "$SCRATCH/work/soak.mosaic" ] || fail "the soak's map is not where --work says"
# A stop signal ends a long drive between two batches of frames with the figures of the frames
# localized so far, and the exit status a shell gives a terminated program.
"$MOSAICLOC" --quiet --json bench soak --frames 1000000 --route loop --speed-mps 1.0 --config "$SCRATCH/drive.yaml" \
  --work "$SCRATCH/stopped" >"$SCRATCH/stopped.json" 2>"$SCRATCH/stopped.err" &
SOAK=$!
for _ in $(seq 1800); do [ -f "$SCRATCH/stopped/soak.mosaic" ] && break; sleep 0.1; done  # the map is built
sleep 3
kill -TERM "$SOAK"
STATUS=0
wait "$SOAK" || STATUS=$?
[ "$STATUS" = 143 ] || fail "a terminated soak exited with $STATUS, not 143: $(tail -3 "$SCRATCH/stopped.err")"
expect_in "$SCRATCH/stopped.err" "their figures are printed"
python3 - "$SCRATCH/stopped.json" <<'PY' || fail "stopped soak"
import json, sys
d = json.load(open(sys.argv[1]))
print({k: d[k] for k in ("stopped", "frames", "fix_rate", "lock_losses", "wrong_fixes", "driven_s", "driven_km")})
assert d["stopped"] == "terminated (SIGTERM)", d["stopped"]
assert 0 < d["frames"] < 1000000 and d["wrong_fixes"] == 0, d
col = {name: i for i, name in enumerate(d["samples_columns"])}
assert d["samples"][-1][col["frames"]] == d["frames"], d["samples"][-1]
assert d["frames"] / 30.0 <= d["driven_s"] < d["frames"] / 30.0 / 0.9 + 1.0, d  # up to the last frame, 5 % dropped
PY
# Bad input is named.
expect_exit 2 "$MOSAICLOC" bench soak --frames 10 --route straight --config "$SCRATCH/none.yaml"
expect_in "$SCRATCH/err" "none.yaml"
finish
