# Bad input is refused with a message naming the file, line or key, exit code 2, and
# nothing is left half-written.
source "$(dirname "$0")/lib.sh"

printf 'route:\n  name: loop\n  sped_mps: 2\ncamera:\n  mm_per_px: -1\n' > "$SCRATCH/typo.yaml"
expect_exit 2 "$MOSAICLOC" simulate --out "$SCRATCH/d" --config "$SCRATCH/typo.yaml"
expect_in "$SCRATCH/err" "typo.yaml:3: route.sped_mps: unknown key (did you mean 'speed_mps'?)"
expect_in "$SCRATCH/err" "typo.yaml:5: camera.mm_per_px: must be in"
[ ! -e "$SCRATCH/d" ] || fail "a dataset was written despite the bad configuration"

expect_exit 2 "$MOSAICLOC" simulate --out "$SCRATCH/d" --floor "$SCRATCH/no-such-texture.png" --frames 3
expect_in "$SCRATCH/err" "no-such-texture.png"
[ -z "$(ls -A "$SCRATCH" | grep -v -e typo.yaml -e out -e err)" ] || fail "leftovers: $(ls -A "$SCRATCH")"

expect_exit 2 "$MOSAICLOC" dataset check "$SCRATCH/missing"
expect_in "$SCRATCH/err" "no such dataset directory"

# A good small dataset, then damage it in each way a recording can be damaged.
printf 'camera: {width_px: 64, height_px: 48}\nrun: {frames: 6}\n' > "$SCRATCH/small.yaml"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/ds" --config "$SCRATCH/small.yaml"
expect_exit 0 "$MOSAICLOC" dataset check "$SCRATCH/ds"
expect_exit 2 "$MOSAICLOC" simulate --out "$SCRATCH/ds" --config "$SCRATCH/small.yaml"
expect_in "$SCRATCH/err" "already exists"

cp -r "$SCRATCH/ds" "$SCRATCH/ds1"
rm "$SCRATCH/ds1/cam0/data/$(sed -n 4p "$SCRATCH/ds1/cam0/data.csv" | cut -d, -f2)"
expect_exit 2 "$MOSAICLOC" dataset check "$SCRATCH/ds1"
expect_in "$SCRATCH/err" "cam0/data.csv:4: image"

cp -r "$SCRATCH/ds" "$SCRATCH/ds2"
echo "99999999999,12,oops" >> "$SCRATCH/ds2/encoders/data.csv"
expect_exit 2 "$MOSAICLOC" dataset check "$SCRATCH/ds2"
expect_in "$SCRATCH/err" "right_ticks 'oops' is not an int32 counter value"

cp -r "$SCRATCH/ds" "$SCRATCH/ds3"
sed -i '3{h;d};4{G}' "$SCRATCH/ds3/cam0/data.csv"   # swap lines 3 and 4: a recording's fault, not an error
expect_exit 0 "$MOSAICLOC" dataset check "$SCRATCH/ds3"
expect_in "$SCRATCH/err" "cam0/data.csv: 1 row skipped: not after the row before in time"
expect_in "$SCRATCH/err" "line 4 ("

cp -r "$SCRATCH/ds" "$SCRATCH/ds4"
sed -i 's/mm_per_px:/mm_per_pix:/' "$SCRATCH/ds4/dataset.yaml"
expect_exit 2 "$MOSAICLOC" dataset check "$SCRATCH/ds4"
expect_in "$SCRATCH/err" "camera.mm_per_pix: unknown key (did you mean 'mm_per_px'?)"

cp -r "$SCRATCH/ds" "$SCRATCH/ds5"
sed -i '2s/.*/0.5 1 2 3 0 0 0 1 9/' "$SCRATCH/ds5/groundtruth/data.tum"
expect_exit 2 "$MOSAICLOC" replay --dataset "$SCRATCH/ds5" --out "$SCRATCH/r5" --mode dead-reckoning
expect_in "$SCRATCH/err" "groundtruth/data.tum:2:"
finish
