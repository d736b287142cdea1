#!/usr/bin/env bash
# Builds mosaicloc and runs every test: the system tests (the program run as a user runs it,
# the PLC link against independent peers, tutorials) on an optimized build as shipped, then
# the unit tests under AddressSanitizer and UndefinedBehaviorSanitizer (each unit test runs
# once, there), whose build compiles while the system tests run. The optimized build carries
# no debug information, to keep the run short.
# Both builds are unity builds (four sources compiled as one): OpenCV's, Eigen's and the
# JSON and command-line libraries' headers are parsed and instantiated once per four files
# instead of once per file.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
JOBS=$(nproc)

echo "== build (Release)"
cmake -S . -B build/test -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=4 >/dev/null
cmake --build build/test -j "$JOBS" --target mosaicloc_system_tests

# The sanitizer build compiles while the system tests run, in the scheduler's idle class: many
# system tests wait on real time (the PLC link, live runs, a browser), and the compiler takes
# only the CPU they leave, never delaying them. Its unit tests run afterwards, at normal
# priority, since some of them wait on time-outs too.
# -O1, as the sanitizers' authors advise: at -O0 the rendering of synthetic calibration
# photographs took 195 s for one test, at -O1 10 s. -g1: line tables, enough for the
# sanitizers' stack traces.
mkdir -p build
asan_log=build/asan-build.log
# Its own session, so that a failing system test stops the whole build with the script.
setsid bash -c "cmake -S . -B build/asan -G Ninja -DCMAKE_BUILD_TYPE=Debug '-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g1' \
  -DMOSAICLOC_SANITIZE=ON -DMOSAICLOC_BUILD_BENCHMARKS=OFF -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=4 >/dev/null &&
  chrt --idle 0 cmake --build build/asan -j $JOBS --target mosaicloc_unit_tests" > "$asan_log" 2>&1 &
asan_build=$!
trap 'kill -- -"$asan_build" 2>/dev/null || true' EXIT

echo "== system tests (the sanitizer build compiles meanwhile, at idle priority)"
ctest --test-dir build/test -L system -j "$JOBS" --output-on-failure --timeout 600

echo "== build (AddressSanitizer + UndefinedBehaviorSanitizer)"
if ! wait "$asan_build"; then
  tail -n 60 "$asan_log"
  echo "the sanitizer build failed (whole log: $asan_log)"
  exit 1
fi
trap - EXIT
tail -n 1 "$asan_log"
echo "== unit tests under sanitizers"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build/asan -L unit -j "$JOBS" --output-on-failure --timeout 300
