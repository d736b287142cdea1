# Helpers for the CLI tests. Usage: source lib.sh; the first argument of the test is the program.
set -u
MOSAICLOC=$1
SCRATCH=$(mktemp -d)
FAILURES=0
# The scratch folder goes with the test, unless asked for (KEEP_SCRATCH) or a check failed:
# then it stays, for a failure that timing made (a live run's) to be looked at.
trap 'if [ -n "${KEEP_SCRATCH:-}" ] || [ "$FAILURES" -gt 0 ]; then echo "scratch kept: $SCRATCH" >&2; else rm -rf "$SCRATCH"; fi' EXIT

fail() { echo "FAIL: $*" >&2; FAILURES=$((FAILURES + 1)); }

# expect_exit CODE CMD...: runs CMD, keeps stdout in $SCRATCH/out and stderr in $SCRATCH/err.
expect_exit() {
  local expected=$1; shift
  "$@" >"$SCRATCH/out" 2>"$SCRATCH/err"
  local code=$?
  [ "$code" -eq "$expected" ] || fail "exit $code (wanted $expected): $* -- $(head -c 600 "$SCRATCH/err")"
}

# expect_in FILE TEXT: FILE contains TEXT.
expect_in() { grep -qF -- "$2" "$1" || fail "'$2' not in $1: $(head -c 600 "$1")"; }

# json_check FILE EXPR...: every Python expression holds for the JSON object d read from FILE
# (a script may define its own, printing the figures it is about).
json_check() {
  local file=$1
  shift
  python3 - "$file" "$@" <<'PY' || fail "$file: $*"
import json, sys
d = json.load(open(sys.argv[1]))
for check in sys.argv[2:]:
    assert eval(check), check + "   with " + json.dumps({k: v for k, v in d.items() if k in check})
PY
}

finish() {
  if [ "$FAILURES" -gt 0 ]; then echo "$FAILURES check(s) failed" >&2; exit 1; fi
  echo "all checks passed"
}
