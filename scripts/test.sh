#!/usr/bin/env bash
# Builds mosaicloc and runs every test: the system tests (the program run as a user runs it,
# the PLC link against independent peers, tutorials) on an optimized build as shipped, then
# the unit tests under AddressSanitizer and UndefinedBehaviorSanitizer (each unit test runs
# once, there). The optimized build carries no debug information, to keep the run short.
# Both builds are unity builds (four sources compiled as one): OpenCV's, Eigen's and the
# JSON and command-line libraries' headers are parsed and instantiated once per four files
# instead of once per file.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
JOBS=$(nproc)

SANITIZED=(-DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g1" -DMOSAICLOC_SANITIZE=ON
  -DMOSAICLOC_BUILD_BENCHMARKS=OFF -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=4)

echo "== build (Release)"
cmake -S . -B build/test -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=4 >/dev/null
cmake --build build/test -j "$JOBS" --target mosaicloc_system_tests

# The sanitizer build (-O1, as the sanitizers' authors advise: at -O0 the rendering of synthetic
# calibration photographs took 195 s for one test, at -O1 10 s; -g1: line tables, enough for
# the sanitizers' stack traces) runs beside the system tests at the lowest priority: it takes
# only the processor time they leave (the live tests run one at a time, in real time, and wait
# on their PLC and camera), so their timing is theirs and the run is shorter by what it fills.
cmake -S . -B build/asan -G Ninja "${SANITIZED[@]}" >/dev/null
SANITIZER_BUILD_LOG=build/asan-build.log
# A process group of its own, so that a failed system test stops all of it.
setsid nice -n 19 cmake --build build/asan -j "$JOBS" --target mosaicloc_unit_tests >"$SANITIZER_BUILD_LOG" 2>&1 &
SANITIZER_BUILD=$!
trap 'kill -- -"$SANITIZER_BUILD" 2>/dev/null || true' EXIT

echo "== system tests (the sanitizer build beside them: $SANITIZER_BUILD_LOG)"
ctest --test-dir build/test -L system -j "$JOBS" --output-on-failure --timeout 600

echo "== build (AddressSanitizer + UndefinedBehaviorSanitizer)"
if ! wait "$SANITIZER_BUILD"; then
  tail -n 60 "$SANITIZER_BUILD_LOG"
  echo "the sanitizer build failed: $SANITIZER_BUILD_LOG" >&2
  exit 1
fi
trap - EXIT
tail -n 1 "$SANITIZER_BUILD_LOG"
echo "== unit tests under sanitizers"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build/asan -L unit -j "$JOBS" --output-on-failure --timeout 300
