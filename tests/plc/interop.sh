# Interoperability with mbpoll, an independent Modbus client: what mosaicloc's PLC simulator
# serves and what mosaicloc's server role reads and writes are exactly what mbpoll sees, in
# both word orders. (The pymodbus peers are in end_to_end.sh.)
source "$(dirname "$0")/lib.sh"
command -v mbpoll >/dev/null || { echo "mbpoll is not installed: run scripts/install-deps.sh"; exit 1; }
make_site site 1.0
FIRST=$(sed -n 2p "$SCRATCH/site-run/encoders/data.csv")   # timestamp,left,right
LEFT=$(echo "$FIRST" | cut -d, -f2)
RIGHT=$(echo "$FIRST" | cut -d, -f3)
NEVER=9999999999   # a start far ahead: the counters hold the first sample

# mbpoll ARGS...: one request to 127.0.0.1, values printed one per line (stdout kept in $SCRATCH/mb).
mb() { mbpoll -m tcp -a 1 -0 -1 "$@" >"$SCRATCH/mb" 2>&1 || fail "mbpoll $*: $(tail -2 "$SCRATCH/mb")"; }
values() { grep -E '^\[[0-9]+\]:' "$SCRATCH/mb" | awk '{print $2}' | tr '\n' ' ' | sed 's/ $//'; }

for order in high_first low_first; do
  # mbpoll's -B reads 32-bit values high word first; without it, low word first.
  B=""; [ "$order" = high_first ] && B="-B"
  printf 'map: x.mosaic\nplc:\n  registers: {word_order: %s}\n' "$order" > "$SCRATCH/map-$order.yaml"
  PORT=$(free_port)
  "$MOSAICLOC" --quiet --json plc-sim --dataset "$SCRATCH/site-run" --port "$PORT" --start-unix $NEVER \
    --request-period-ms 0 --heartbeat-period-ms 50 --config "$SCRATCH/map-$order.yaml" \
    --fixes-out "$SCRATCH/fixes-$order.csv" >"$SCRATCH/sim-$order.json" 2>"$SCRATCH/sim-$order.err" &
  SIM=$!
  wait_port "$PORT"
  mb -r 0 -c 2 -t 4:int $B -p "$PORT" 127.0.0.1
  [ "$(values)" = "$LEFT $RIGHT" ] || fail "$order: plc-sim serves ticks '$(values)', the dataset has '$LEFT $RIGHT'"
  mb -r 4 -c 1 -t 4 -p "$PORT" 127.0.0.1; BEAT1=$(values)
  sleep 0.3
  mb -r 4 -c 1 -t 4 -p "$PORT" 127.0.0.1; BEAT2=$(values)
  [ "$BEAT1" != "$BEAT2" ] || fail "$order: the heartbeat does not beat ($BEAT1)"
  # mbpoll writes a fix the way mosaicloc does (status block, then the pose); plc-sim decodes it.
  mb -r 106 -t 4 -p "$PORT" 127.0.0.1 2 640 5 9
  mb -r 100 -t 4:int $B -p "$PORT" 127.0.0.1 -- 123456 -78901 -1745329
  kill $SIM; wait $SIM
  expect_in "$SCRATCH/fixes-$order.csv" ",1234.56,-789.01,-1.745329,2,640,5,9,"
done

# mosaicloc as the server, low word first: mbpoll plays the PLC.
PORT=$(free_port)
cat > "$SCRATCH/server.yaml" <<YAML
map: $SCRATCH/site.mosaic
camera: {source: dataset, dataset: {path: $SCRATCH/site-run, start_unix_s: $NEVER}}
plc: {role: server, port: $PORT, registers: {word_order: low_first}}
start: {x_mm: 1234.56, y_mm: -789.01, yaw_deg: 10.0}
YAML
"$MOSAICLOC" --quiet --json run --config "$SCRATCH/server.yaml" --record "$SCRATCH/rec" \
  >"$SCRATCH/server.jsonl" 2>"$SCRATCH/server.err" &
RUN=$!
wait_port "$PORT"
mb -r 0 -t 4:int -p "$PORT" 127.0.0.1 -- -5 70000     # left, right ticks
mb -r 4 -t 4 -p "$PORT" 127.0.0.1 1 0                 # heartbeat, fix request
sleep 0.3
mb -r 100 -c 3 -t 4:int -p "$PORT" 127.0.0.1
[ "$(values)" = "123456 -78901 174533" ] || fail "mosaicloc serves the fix as '$(values)'"
mb -r 106 -c 4 -t 4 -p "$PORT" 127.0.0.1
[ "$(values | cut -d' ' -f1,3)" = "0 0" ] || fail "status and echo before any fix: '$(values)'"
mb -r 5 -t 4 -p "$PORT" 127.0.0.1 1                   # ask for a fix
sleep 0.2
mb -r 108 -c 1 -t 4 -p "$PORT" 127.0.0.1
[ "$(values)" = "1" ] || fail "the fix request was not echoed: '$(values)'"
# Ctrl-C: a clean stop, the recording committed.
kill -INT $RUN
wait $RUN || fail "run in the server role did not stop cleanly on SIGINT: $(tail -3 "$SCRATCH/server.err")"
json_check "$SCRATCH/server.jsonl" 'd["stopped"] == "interrupted (SIGINT)"' 'd["requests"] == 1' 'd["answered"] == 1' \
  'd["encoder_samples"] == 1'
# What mbpoll wrote is what mosaicloc recorded.
[ "$(tail -1 "$SCRATCH/rec/encoders/data.csv" | cut -d, -f2,3)" = "-5,70000" ] ||
  fail "recorded ticks: $(tail -1 "$SCRATCH/rec/encoders/data.csv")"
finish
