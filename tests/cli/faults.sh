# Faults the computer on a vehicle meets, each reported clearly and with nothing lost:
# - long commands stopped by SIGINT or SIGTERM: they say where they stopped and what is kept,
#   exit with 128 + the signal, and leave no half-written dataset, map or report (an
#   interrupted `map build` goes on with --resume to the same map; `map poses`, `map index`
#   and `map quality` leave the map as it was);
# - a full disk (RLIMIT_FSIZE: the files may not grow) while a dataset or a map is written,
#   and while a drive extends its map: the error names the file and the reason, the map
#   checks clean afterwards, and localization goes on to the end of the drive;
# - the map locked by another process: a clear error, and map keeping stops, not the drive;
# - a recording with frames recorded twice, out of order, missing for a second, and behind a
#   clock that stepped back: replayed with those rows skipped and counted, and no wrong fix;
# - wheel encoders that stall for a second (a loose cable, a frozen PLC counter) and then jump
#   to where the wheels are: the camera holds the pose, and no fix is wrong.
# Usage: faults.sh MOSAICLOC
source "$(dirname "$0")/lib.sh"

# stop_at SIGNAL 'STAGE: PERCENT' CMD...: runs CMD, sends SIGNAL once the progress of its
# stage STAGE reaches PERCENT (a command may report stages before it, as a replay checks its
# map first); stdout, stderr and the exit code in $SCRATCH/out, err and code.
stop_at() {
  local signal=$1 progress=$2
  shift 2
  "$@" >"$SCRATCH/out" 2>"$SCRATCH/err" &
  local pid=$!
  for _ in $(seq 1200); do
    grep -q "^$progress% (" "$SCRATCH/err" && break
    kill -0 $pid 2>/dev/null || break
    sleep 0.05
  done
  kill "-$signal" $pid 2>/dev/null
  wait $pid
  echo $? >"$SCRATCH/code"
}
expect_code() { [ "$(cat "$SCRATCH/code")" = "$1" ] || fail "exit $(cat "$SCRATCH/code") (wanted $1): $(tail -c 400 "$SCRATCH/err")"; }
# small_files KB CMD...: CMD where no file may grow past KB kilobytes (as on a full disk: the
# write fails with EFBIG instead of the process being killed by SIGXFSZ).
small_files() {
  local kb=$1
  shift
  (trap '' XFSZ; ulimit -f "$kb"; exec "$@")
}
# no_leftovers DIR: no hidden staging or temporary files in DIR.
no_leftovers() {
  local left
  left=$(find "$1" -maxdepth 1 -name '.*partial*' -o -maxdepth 1 -name '.*.tmp.*' | head -3)
  [ -z "$left" ] || fail "left behind in $1: $left"
}

M=$MOSAICLOC
W=$SCRATCH/w
mkdir -p "$W"
"$M" --quiet simulate --out "$W/ds" --frames 240 --seed 3 >/dev/null || fail "simulate failed"
"$M" --quiet map build --dataset "$W/ds" --out "$W/map.db" >/dev/null || fail "map build failed"

echo "== stopped by a signal"
stop_at INT "simulate: 25" "$M" simulate --out "$W/stopped-ds" --frames 240 --seed 3 --threads 1
expect_code 130
expect_in "$SCRATCH/err" "simulate: interrupted (SIGINT) at "
expect_in "$SCRATCH/err" "no dataset was written"
[ ! -e "$W/stopped-ds" ] || fail "an interrupted simulate left $W/stopped-ds"
no_leftovers "$W"

stop_at TERM "map build: 75" "$M" map build --dataset "$W/ds" --out "$W/resumed.db"
expect_code 143
expect_in "$SCRATCH/err" "map build: terminated (SIGTERM) at "
expect_in "$SCRATCH/err" "the same command with --resume goes on from there"
[ ! -e "$W/resumed.db" ] || fail "an interrupted map build left a map"
[ -e "$W/resumed.db.checkpoint" ] || fail "an interrupted map build kept no checkpoint"
expect_exit 0 "$M" map build --dataset "$W/ds" --out "$W/resumed.db" --resume
expect_exit 0 "$M" map check "$W/resumed.db"
# The resumed build paints the same mosaic as the build that ran through.
"$M" --quiet map export "$W/map.db" --out "$W/whole.png" --level 2 >/dev/null
"$M" --quiet map export "$W/resumed.db" --out "$W/resumed.png" --level 2 >/dev/null
cmp -s "$W/whole.png" "$W/resumed.png" || fail "the resumed map differs from the one built in one go"

stop_at TERM "replay: 25" "$M" replay --dataset "$W/ds" --map "$W/map.db" --out "$W/stopped-report"
expect_code 143
expect_in "$SCRATCH/err" "replay: terminated (SIGTERM) at "
[ ! -e "$W/stopped-report/metrics.json" ] || fail "an interrupted replay wrote metrics"

# The map's other long commands stop the same way: nothing half-written, the map as it was.
stop_at TERM "map poses: 25" "$M" map poses --dataset "$W/ds" --out "$W/stopped.tum" --report "$W/stopped-poses"
expect_code 143
expect_in "$SCRATCH/err" "map poses: terminated (SIGTERM) at "
[ ! -e "$W/stopped.tum" ] && [ ! -e "$W/stopped-poses" ] || fail "an interrupted map poses wrote its trajectory or report"
no_leftovers "$W"
"$M" --quiet --json map info "$W/map.db" >"$W/info-before.json" || fail "map info failed"
for stage in index quality; do
  cp "$W/map.db" "$W/stopped-$stage.db"
  if [ "$stage" = index ]; then
    stop_at TERM "map index: 25" "$M" map index "$W/stopped-$stage.db"
  else
    stop_at TERM "map quality: 50" "$M" map quality "$W/stopped-$stage.db" --out "$W/stopped-quality" --rebuild
  fi
  expect_code 143
  expect_in "$SCRATCH/err" "map $stage: terminated (SIGTERM) at "
  expect_in "$SCRATCH/err" "as they were"
  expect_exit 0 "$M" map check "$W/stopped-$stage.db"
  "$M" --quiet --json map info "$W/stopped-$stage.db" >"$W/info-after.json" || fail "map info failed"
  python3 - "$W/info-before.json" "$W/info-after.json" <<'PY' || fail "an interrupted map $stage changed the map"
import json, sys
before, after = (json.load(open(f)) for f in sys.argv[1:3])
for key in ("tiles", "place_index", "quality", "updates"):
    assert before[key] == after[key], (key, before[key], after[key])
PY
done

echo "== a full disk"
expect_exit 1 small_files 100 "$M" simulate --out "$W/full-ds" --frames 60 --seed 3
expect_in "$SCRATCH/err" "cannot write (File too large: the disk is full or the file may not grow"
[ ! -e "$W/full-ds" ] || fail "simulate on a full disk left $W/full-ds"
no_leftovers "$W"

expect_exit 1 small_files 4096 "$M" map build --dataset "$W/ds" --out "$W/full.db"
expect_in "$SCRATCH/err" "the disk is full or the file may not grow"
[ ! -e "$W/full.db" ] || fail "map build on a full disk left a map"
expect_exit 0 "$M" map build --dataset "$W/ds" --out "$W/full.db" --resume
expect_exit 0 "$M" map check "$W/full.db"

# A map of the first half of the drive; the replay of the whole drive extends it, where the
# map's file may not grow: map keeping stops, the drive is localized to its end, the report is
# written, and the map is the one it was.
mkdir -p "$W/half"
cp -r "$W/ds/." "$W/half"
head -121 "$W/ds/cam0/data.csv" >"$W/half/cam0/data.csv"
"$M" --quiet map build --dataset "$W/half" --out "$W/half.db" >/dev/null || fail "map build (half) failed"
cp "$W/half.db" "$W/kept.db"
expect_exit 0 "$M" --json replay --dataset "$W/ds" --map "$W/kept.db" --mapping --out "$W/kept"
json_check "$W/kept/metrics.json" 'd["map_extension_tiles"] > 0' 'd["wrong_fixes"] == 0'
cp "$W/half.db" "$W/full-half.db"
size_kb=$(( $(stat -c %s "$W/half.db") / 1024 + 64 ))
expect_exit 1 small_files "$size_kb" "$M" --json replay --dataset "$W/ds" --map "$W/full-half.db" --mapping --out "$W/full-replay"
expect_in "$SCRATCH/err" "map keeping stopped"
expect_in "$SCRATCH/err" "its results are written, and the map holds what was committed before"
json_check "$W/full-replay/metrics.json" 'd["wrong_fixes"] == 0' \
  "d['fix_rate'] == $(python3 -c "import json; print(json.load(open('$W/kept/metrics.json'))['fix_rate'])")"
expect_exit 0 "$M" map check "$W/full-half.db"
expect_exit 0 "$M" --json map history "$W/full-half.db"
json_check "$SCRATCH/out" 'len(d["updates"]) == 0'

echo "== the map locked by another process"
# lock MAP: another process holds MAP's write lock until `unlock`, with the map in
# write-ahead-log mode, as a map a run has written is, so that it can still be read.
lock() {
  rm -f "$SCRATCH/locked" "$SCRATCH/release"
  python3 - "$1" "$SCRATCH/locked" "$SCRATCH/release" <<'PY' &
import os, sqlite3, sys, time
db = sqlite3.connect(sys.argv[1], isolation_level=None, timeout=10)
db.execute("PRAGMA journal_mode=WAL")
db.execute("BEGIN EXCLUSIVE")
open(sys.argv[2], "w").close()
for _ in range(1200):
    if os.path.exists(sys.argv[3]): break
    time.sleep(0.05)
PY
  LOCKER=$!
  for _ in $(seq 200); do [ -e "$SCRATCH/locked" ] && break; sleep 0.05; done
}
unlock() { touch "$SCRATCH/release"; wait $LOCKER; }
cp "$W/half.db" "$W/locked.db"
lock "$W/locked.db"
expect_exit 1 "$M" map index "$W/locked.db"
expect_in "$SCRATCH/err" "database is locked (another process is writing to the file"
expect_exit 1 "$M" --json replay --dataset "$W/ds" --map "$W/locked.db" --mapping --out "$W/locked-replay"
expect_in "$SCRATCH/err" "map keeping stopped"
json_check "$W/locked-replay/metrics.json" 'd["wrong_fixes"] == 0' \
  "d['fix_rate'] == $(python3 -c "import json; print(json.load(open('$W/kept/metrics.json'))['fix_rate'])")"
unlock
expect_exit 0 "$M" map check "$W/locked.db"

echo "== recordings with rows recorded twice, out of order, missing, and behind a clock that stepped back"
# fault DIR: edits the recording in DIR as a faulty recorder would have written it (see above).
fault() {
  python3 - "$@" <<'PY'
import sys
root, kind = sys.argv[1], sys.argv[2]
def rows(name):
    lines = open(f"{root}/{name}").read().splitlines()
    return lines[0], [l.split(",") for l in lines[1:]]
def write(name, header, body):
    open(f"{root}/{name}", "w").write("\n".join([header] + [",".join(r) for r in body]) + "\n")
header, frames = rows("cam0/data.csv")
_, samples = rows("encoders/data.csv")
if kind == "rows":
    frames.insert(40, list(frames[40]))                # a frame recorded twice
    frames[60], frames[61] = frames[61], frames[60]    # two out of order
    del frames[100:130]                                # a second missing: the time jumps
    samples.insert(200, list(samples[200]))            # a sample recorded twice
elif kind == "stall":
    # The counters stop 3 s into the drive and read the wheels again 1 s later.
    start, frozen = int(samples[0][0]), None
    for r in samples:
        if 3_000_000_000 <= int(r[0]) - start < 4_000_000_000:
            frozen = frozen or (r[1], r[2])
            r[1], r[2] = frozen
else:
    # The recorder's clock steps 0.3 s back 4 s into the drive: every later row is stamped
    # 0.3 s early (the ground truth, kept in true time, would no longer match: it goes).
    step, start = 300_000_000, 4_000_000_000 + int(frames[0][0])
    for r in frames + samples:
        if int(r[0]) >= start: r[0] = str(int(r[0]) - step)
write("cam0/data.csv", header, frames)
write("encoders/data.csv", _, samples)
PY
}
for kind in rows clock stall; do
  mkdir -p "$W/$kind"
  cp -r "$W/ds/." "$W/$kind"
  fault "$W/$kind" $kind
done
rm -r "$W/clock/groundtruth"
expect_exit 0 "$M" dataset check "$W/rows"
expect_in "$SCRATCH/out" "skipped, not after the row before in time: 2 frames, 1 encoder samples"
expect_exit 0 "$M" --json replay --dataset "$W/rows" --map "$W/map.db" --out "$W/rows-report"
expect_in "$SCRATCH/err" "cam0/data.csv: 2 rows skipped"
json_check "$W/rows-report/metrics.json" 'd["skipped_frames"] == 2' 'd["skipped_encoder_samples"] == 1' \
  'd["wrong_fixes"] == 0' 'd["fix_rate"] >= 0.95'
expect_exit 0 "$M" --json replay --dataset "$W/clock" --map "$W/map.db" --out "$W/clock-report"
json_check "$W/clock-report/metrics.json" 'd["skipped_frames"] >= 8' 'd["skipped_encoder_samples"] >= 29' \
  'd["lock_losses"] == 0' 'd["fix_rate"] >= 0.95'
expect_exit 0 "$M" --json replay --dataset "$W/stall" --map "$W/map.db" --out "$W/stall-report"
json_check "$W/stall-report/metrics.json" 'd["wrong_fixes"] == 0' 'd["lock_losses"] == 0' 'd["fix_rate"] >= 0.85'

finish
