# A dataset over a real texture validates, and the same seed gives byte-identical output.
source "$(dirname "$0")/lib.sh"
TEXTURE="${MOSAICLOC_SHARED_DATA:-}/textures/asphalt_02_2048.jpg"
if [ ! -f "$TEXTURE" ]; then
  echo "skipped: shared texture $TEXTURE not found (the shared data folder sits beside the project)"
  exit 77
fi
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/a" --floor "$TEXTURE" --route loop --frames 300
expect_exit 0 "$MOSAICLOC" dataset check "$SCRATCH/a"
expect_in "$SCRATCH/out" "300 frames"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/b" --floor "$TEXTURE" --route loop --frames 300 --threads 1
diff -r "$SCRATCH/a" "$SCRATCH/b" >/dev/null || fail "same seed, different bytes"
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/c" --floor "$TEXTURE" --route loop --frames 30 --seed 2
expect_exit 0 "$MOSAICLOC" --quiet simulate --out "$SCRATCH/d" --floor "$TEXTURE" --route loop --frames 30 --seed 3
diff -rq "$SCRATCH/c/cam0" "$SCRATCH/d/cam0" >/dev/null && fail "different seeds, same images"
finish
