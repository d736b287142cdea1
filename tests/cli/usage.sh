# Help, version and usage errors: exit 0 for help, 2 for bad usage with a one-line reason.
source "$(dirname "$0")/lib.sh"
expect_exit 0 "$MOSAICLOC" --help
expect_in "$SCRATCH/out" "simulate"
expect_in "$SCRATCH/out" "replay"
expect_exit 0 "$MOSAICLOC" simulate --help
expect_in "$SCRATCH/out" "--floor-seed"
expect_exit 0 "$MOSAICLOC" --version
expect_exit 2 "$MOSAICLOC"
expect_exit 2 "$MOSAICLOC" teleport
expect_exit 2 "$MOSAICLOC" simulate
expect_in "$SCRATCH/err" "--out is required"
expect_exit 2 "$MOSAICLOC" simulate --out "$SCRATCH/d" --route spiral
expect_exit 2 "$MOSAICLOC" simulate --out "$SCRATCH/d" --frames 10 --laps 2
finish
