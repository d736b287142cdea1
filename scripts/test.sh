#!/usr/bin/env bash
# Builds mosaicloc and runs every test: unit tests and system tests (the program run as a
# user runs it, tutorials) on a RelWithDebInfo build, then the unit tests again under
# AddressSanitizer and UndefinedBehaviorSanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
JOBS=$(nproc)

echo "== build (RelWithDebInfo)"
cmake -S . -B build/test -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build/test -j "$JOBS"
echo "== all tests"
ctest --test-dir build/test -j "$JOBS" --output-on-failure --timeout 600

echo "== build (AddressSanitizer + UndefinedBehaviorSanitizer)"
cmake -S . -B build/asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DMOSAICLOC_SANITIZE=ON \
  -DMOSAICLOC_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build build/asan -j "$JOBS" --target mosaicloc_unit_tests
echo "== unit tests under sanitizers"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build/asan -L unit -j "$JOBS" --output-on-failure --timeout 900
