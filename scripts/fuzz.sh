#!/usr/bin/env bash
# Fuzzes the readers of what users and their files hand mosaicloc (tests/fuzz): builds every
# target with clang's libFuzzer under AddressSanitizer and UndefinedBehaviorSanitizer, runs each
# for SECONDS (or until a finding), and prints executions, coverage and findings per target.
# A finding's input is left in build/fuzz/findings/TARGET/; once fixed, copy it into
# tests/fuzz/corpus/TARGET/, where every build's unit tests run it again.
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...]   (default 60 s each, every target)
#        FUZZ_RUNS=N scripts/fuzz.sh ...          (N executions each instead, SECONDS the cap)
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${1:-60}
shift || true
./scripts/install-deps.sh
missing=()
for package in clang libclang-rt-14-dev; do
  [ "$(dpkg-query -W -f='${db:Status-Status}' "$package" 2>/dev/null || true)" = installed ] || missing+=("$package")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO=sudo
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

BUILD=build/fuzz
# The readers take files: on a RAM disk where there is one.
if [ -d /dev/shm ] && [ -w /dev/shm ]; then export TMPDIR=/dev/shm; fi
CXX=clang++ cmake -S . -B "$BUILD" -G Ninja -DCMAKE_BUILD_TYPE=Debug "-DCMAKE_CXX_FLAGS_DEBUG=-O1 -g" \
  -DMOSAICLOC_FUZZ=ON -DMOSAICLOC_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$BUILD" -j "$(nproc)" --target mosaicloc_fuzzers

targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fixes_csv tum dataset_yaml dataset_csv frame_png tile_png config g2o map_metadata modbus console_http)
declare -A MAX_LEN=([tile_png]=70000 [frame_png]=70000)
printf '%-14s %12s %10s %10s %9s\n' target executions "exec/s" coverage findings
status=0
for target in "${targets[@]}"; do
  corpus="$BUILD/corpus/$target"
  findings="$BUILD/findings/$target"
  mkdir -p "$corpus" "$findings"
  log="$BUILD/fuzz-$target.log"
  runs_arg=()
  [ -z "${FUZZ_RUNS:-}" ] || runs_arg=(-runs="$FUZZ_RUNS")
  set +e
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
    "$BUILD/tests/fuzz/mosaicloc_fuzz_$target" -max_total_time="$SECONDS_EACH" "${runs_arg[@]}" \
    -max_len="${MAX_LEN[$target]:-4096}" \
    -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$findings/" \
    "$corpus" "tests/fuzz/corpus/$target" >"$log" 2>&1
  code=$?
  set -e
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  rate=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo 0)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | grep -o '[0-9]*' || echo 0)
  found=$(find "$findings" -type f | wc -l)
  printf '%-14s %12s %10s %10s %9s\n' "$target" "$runs" "$rate" "$cov" "$found"
  if [ "$code" -ne 0 ] || [ "$found" -gt 0 ]; then
    status=1
    echo "  $target: a finding (exit $code); see $log and $findings" >&2
  fi
done
exit $status
