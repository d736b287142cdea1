# A recording without ground truth, as an integrator replays one at the desk: the report says
# how good the fixes were from the recording alone. A loop is mapped in one slow lap and driven
# twice faster; the drive is replayed with its ground truth and from a copy without it.
#  - The copy's report has every figure that needs no truth, and none that needs it.
#  - Its repeatability from the revisits agrees with the truth's at the same point (the
#    camera's centre) within 20 % or 2 micrometres.
#  - The filter's consistency: most fixes inside the 95 % NIS bound with the shipped odometry
#    model, few with one that claims the wheels are ten times better than they are.
#  - index.html opens in a real browser (headless chromium), its images load, its summary is
#    there; with a plot missing the page shows it.
#  - `report compare` puts the two replays side by side.
source "$(dirname "$0")/lib.sh"
printf 'camera: {width_px: 320, height_px: 240}\n' > "$SCRATCH/map.yaml"
printf 'camera: {width_px: 320, height_px: 240}\nencoders: {left_radius_error: 0.02, right_radius_error: 0.025}\n' \
  > "$SCRATCH/drive.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/map" --config "$SCRATCH/map.yaml" --route loop --laps 1 \
  --speed-mps 0.5 --seed 1
expect_exit 0 "$MOSAICLOC" --quiet map build --dataset "$SCRATCH/map" --out "$SCRATCH/floor.mosaic" --poses groundtruth
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/drive" --config "$SCRATCH/drive.yaml" --route loop \
  --laps 2 --speed-mps 1.5 --seed 2
mkdir -p "$SCRATCH/blind"
cp -r "$SCRATCH/drive/cam0" "$SCRATCH/drive/encoders" "$SCRATCH/drive/dataset.yaml" "$SCRATCH/blind/"
expect_exit 0 "$MOSAICLOC" dataset check "$SCRATCH/blind"

expect_exit 0 "$MOSAICLOC" --quiet --json replay --dataset "$SCRATCH/drive" --map "$SCRATCH/floor.mosaic" \
  --out "$SCRATCH/truth"
expect_exit 0 "$MOSAICLOC" --quiet replay --dataset "$SCRATCH/blind" --map "$SCRATCH/floor.mosaic" \
  --out "$SCRATCH/blind-report"
expect_in "$SCRATCH/out" "revisit repeatability"
expect_in "$SCRATCH/out" "index.html"
for file in index.html metrics.json fixes.csv estimate.tum map_state.png map_quality.png timelines.png; do
  [ -s "$SCRATCH/blind-report/$file" ] || fail "report file $file missing or empty without ground truth"
done
for file in trajectory.png position_error.png heading_error.png; do
  [ -e "$SCRATCH/blind-report/$file" ] && fail "$file needs the ground truth, yet it was written"
done
python3 - "$SCRATCH/truth/metrics.json" "$SCRATCH/blind-report/metrics.json" <<'PY' || fail "figures without truth"
import json, sys
t, b = (json.load(open(f)) for f in sys.argv[1:3])
print("with truth:   ", {k: t[k] for k in ("repeatability_mm", "repeatability_camera_mm", "repeatability_camera_places",
                                          "revisit_repeatability_mm", "revisit_places", "nis_inside_95_share", "nis_mean")})
print("without truth:", {k: b[k] for k in ("fix_rate", "revisit_repeatability_mm", "revisit_places", "revisit_failures",
                                          "estimate_path_length_m", "no_fix_reasons", "frames_by_state")})
for key in ("estimate_path_length_m", "estimate_speed_mean_mps", "estimate_speed_p99_mps", "frames_by_state",
            "fixes_by_state", "frames_by_mode", "fixes_by_mode", "nis_fixes", "nis_inside_95_share", "nis_mean", "innovation_sigma_ratio",
            "revisit_repeatability_mm", "revisit_places", "revisit_visits", "revisit_failures", "processing_fps"):
    assert b[key] is not None, key
for key in ("wrong_fixes", "position_rms_mm", "repeatability_mm", "repeatability_camera_mm", "path_length_m"):
    assert b[key] is None, key
# Two laps of an 11 m loop: the estimate's own path length and top speed.
assert abs(b["estimate_path_length_m"] - t["path_length_m"]) < 0.01 * t["path_length_m"], b
assert 1.3 < b["estimate_speed_p99_mps"] < 1.6, b
# The same recording, the same estimate: the revisits measure what the truth measures.
truth, revisit = t["repeatability_camera_mm"], b["revisit_repeatability_mm"]
assert b["revisit_places"] >= 5 and b["revisit_failures"] == 0, b
assert abs(revisit - truth) <= max(0.2 * truth, 0.002), (truth, revisit)
assert t["revisit_repeatability_mm"] == revisit, "the truth does not enter the revisit figure"
assert b["nis_inside_95_share"] >= 0.9, b
PY

# An odometry model that lies: wheels calibrated exactly and rolling without slip (their radii
# are 2 % and 2.5 % off), so the innovations outgrow their predicted spread. (Claiming slip-free
# wheels alone is not enough of a lie to show: the counts' tick quantization, which the
# prediction carries whatever the wheel model says, is most of the spread a frame at 1.5 m/s
# has here.)
printf 'filter: {wheel_variance_mm: 0.00001, wheel_scale_sigma: 0, wheel_scale_walk_per_sqrt_m: 0}\n' \
  > "$SCRATCH/overconfident.yaml"
expect_exit 0 "$MOSAICLOC" --quiet replay --dataset "$SCRATCH/blind" --map "$SCRATCH/floor.mosaic" \
  --out "$SCRATCH/overconfident" --config "$SCRATCH/overconfident.yaml" --revisit-places 0
python3 - "$SCRATCH/overconfident/metrics.json" <<'PY' || fail "a lying covariance is not reported"
import json, sys
m = json.load(open(sys.argv[1]))
print("overconfident odometry:", {k: m[k] for k in ("nis_inside_95_share", "nis_mean", "innovation_sigma_ratio")})
assert m["nis_inside_95_share"] < 0.5 and m["nis_mean"] > 7.81, m
PY
expect_in "$SCRATCH/overconfident/index.html" "wheel_variance_mm: 0.00001"

# The page in a real browser: every image loads, the summary table is there; nothing comes
# from the network (the page is the directory).
command -v chromium >/dev/null || fail "chromium is not installed (scripts/install-deps.sh installs it)"
browse() {  # REPORT: the page's DOM after load, as headless chromium sees it
  chromium --headless --no-sandbox --disable-gpu --allow-file-access-from-files --virtual-time-budget=5000 \
    --dump-dom "file://$1/index.html" 2>/dev/null
}
browse "$SCRATCH/blind-report" > "$SCRATCH/dom.html"
python3 - "$SCRATCH/dom.html" <<'PY' || fail "index.html in chromium"
import re, sys
dom = open(sys.argv[1]).read()
body = re.search(r'<body data-images="(\d+)" data-images-loaded="(\d+)"', dom)
assert body and int(body.group(1)) >= 3 and body.group(1) == body.group(2), body and body.groups()
assert 'id="summary"' in dom and "revisit_repeatability_mm" in dom, "summary table"
PY
size=$(du -sk "$SCRATCH/blind-report" | cut -f1)
[ "$size" -lt 10240 ] || fail "the report is $size KiB"
rm "$SCRATCH/blind-report/timelines.png"
browse "$SCRATCH/blind-report" > "$SCRATCH/dom.html"
grep -q 'data-images="[0-9]*" data-images-loaded="[0-9]*"' "$SCRATCH/dom.html" || fail "no image count on the page"
python3 -c 'import re,sys; b=re.search(r"data-images=\"(\d+)\" data-images-loaded=\"(\d+)\"", open(sys.argv[1]).read()); sys.exit(b.group(1) == b.group(2))' \
  "$SCRATCH/dom.html" || fail "a missing plot went unnoticed"

# Two replays side by side; a directory that is no report is named.
expect_exit 0 "$MOSAICLOC" report compare "$SCRATCH/truth" "$SCRATCH/overconfident" --top 3
expect_in "$SCRATCH/out" "nis_mean"
expect_in "$SCRATCH/out" "frames that differ most"
expect_exit 0 "$MOSAICLOC" --json report compare "$SCRATCH/truth" "$SCRATCH/blind-report"
python3 -c 'import json,sys; c=json.load(open(sys.argv[1])); f=c["frames"]; assert f["only_a"] == 0 and f["only_b"] == 0 and f["position_difference_rms_mm"] == 0, f' \
  "$SCRATCH/out" || fail "the same recording replayed twice differs"
expect_exit 2 "$MOSAICLOC" report compare "$SCRATCH/truth" "$SCRATCH/map"
expect_in "$SCRATCH/err" "map/metrics.json"
finish
