#!/usr/bin/env bash
# Builds mosaicloc and runs every test: the system tests (the program run as a user runs it,
# the PLC link against independent peers, tutorials) on an optimized build as shipped, then
# the unit tests under AddressSanitizer and UndefinedBehaviorSanitizer (each unit test runs
# once, there). The optimized build carries no debug information, to keep the run short.
# Both builds are unity builds (four sources compiled as one) with a precompiled header: the
# standard library's, Eigen's, OpenCV's, the JSON and YAML libraries' headers are parsed once
# per build, what else they include once per four files.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
JOBS=$(nproc)

echo "== build (Release)"
cmake -S . -B build/test -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=4 \
  -DMOSAICLOC_PRECOMPILED_HEADERS=ON >/dev/null
cmake --build build/test -j "$JOBS" --target mosaicloc_system_tests

echo "== system tests"
ctest --test-dir build/test -L system -j "$JOBS" --output-on-failure --timeout 600

echo "== build (AddressSanitizer + UndefinedBehaviorSanitizer)"
# -O1, as the sanitizers' authors advise: at -O0 the rendering of synthetic calibration
# photographs took 195 s for one test, at -O1 10 s. -g1: line tables, enough for the
# sanitizers' stack traces.
cmake -S . -B build/asan -G Ninja -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g1" -DMOSAICLOC_SANITIZE=ON \
  -DMOSAICLOC_BUILD_BENCHMARKS=OFF -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=4 \
  -DMOSAICLOC_PRECOMPILED_HEADERS=ON >/dev/null
cmake --build build/asan -j "$JOBS" --target mosaicloc_unit_tests
echo "== unit tests under sanitizers"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build/asan -L unit -j "$JOBS" --output-on-failure --timeout 300
