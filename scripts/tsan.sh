#!/usr/bin/env bash
# ThreadSanitizer over everything that runs on threads of its own: the unit tests of the
# modules with threads (the PLC link and register server, the map's tile prefetcher, the
# console's HTTP server, the simulator's renderers, the live run's parts) and the live
# system tests (`mosaicloc run` with its camera, tracking, PLC, map-keeping and console
# threads against plc-sim and pymodbus PLCs). Not part of scripts/test.sh: the build alone
# takes about 20 minutes on two cores, and the live tests' real-time figures do not hold
# under ThreadSanitizer's slowdown (their pass or fail is printed; the race reports are the
# verdict). Exit status 1 when ThreadSanitizer reported anything.
#
#   ./scripts/tsan.sh             build, then run all of the above
#   ./scripts/tsan.sh unit        only the unit tests
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/install-deps.sh
WHAT=${1:-all}
BUILD=build/tsan
REPORTS="$PWD/$BUILD/reports"

echo "== build (ThreadSanitizer)"
# -O1 -g1 as for the other sanitizers: fast enough, with line tables for the reports.
cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g1" -DMOSAICLOC_TSAN=ON \
  -DMOSAICLOC_BUILD_BENCHMARKS=OFF -DCMAKE_UNITY_BUILD=ON -DCMAKE_UNITY_BUILD_BATCH_SIZE=4 >/dev/null
UNITS=(io runtime mosaic console sim)
TARGETS=(mosaicloc)
for unit in "${UNITS[@]}"; do TARGETS+=("mosaicloc_${unit}_test"); done
cmake --build "$BUILD" -j "$(nproc)" --target "${TARGETS[@]}"

rm -rf "$REPORTS"
mkdir -p "$REPORTS"
# Reports go to files, one per process, and never stop a run: every test runs to its end.
# OpenMP's, OpenCV's and TBB's own thread pools are not instrumented; what they do inside
# themselves is left out (tests/tsan.supp), what our code does around them is not. The longer
# history lets ThreadSanitizer restore the stacks of a pool's worker (which the suppressions
# are matched against) instead of reporting a loop body against the code after its join.
export TSAN_OPTIONS="halt_on_error=0 exitcode=0 second_deadlock_stack=1 history_size=7 log_path=$REPORTS/tsan \
suppressions=$PWD/tests/tsan.supp"
PATTERN=$(IFS='|'; echo "${UNITS[*]}")
echo "== unit tests under ThreadSanitizer"
ctest --test-dir "$BUILD" -R "^($PATTERN):" -j "$(nproc)" --timeout 900 || echo "(some unit tests failed: see above)"
if [ "$WHAT" = all ]; then
  echo "== live system tests under ThreadSanitizer (real-time checks may fail here; races are the verdict)"
  ctest --test-dir "$BUILD" -R '^plc_' --timeout 900 || echo "(some live tests failed under the slowdown: see above)"
fi

echo "== ThreadSanitizer reports"
shopt -s nullglob
files=("$REPORTS"/tsan.*)
if [ ${#files[@]} -eq 0 ]; then
  echo "none"
  exit 0
fi
grep -h "^SUMMARY: ThreadSanitizer" "${files[@]}" | sort | uniq -c | sort -rn
echo "${#files[@]} process(es) reported; the full reports: $REPORTS"
exit 1
