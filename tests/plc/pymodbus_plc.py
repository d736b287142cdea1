#!/usr/bin/python3
"""A PLC written with Debian's python3-pymodbus: an independent Modbus peer for mosaicloc.

It plays a dataset's encoder counters in real time with the register map of design.md
section 6 (the file's two counters in registers 0-3; a mecanum vehicle's rear two also in 8-11), beats a heartbeat, asks for fixes, and records every fix it receives with its
error against the dataset's ground truth.

  --role server  the PLC is the Modbus server; mosaicloc polls it (mosaicloc's client role)
  --role client  the PLC writes into mosaicloc's registers and reads the fixes (server role)

Faults, for the fault tests (times in seconds of dataset time):
  --freeze-heartbeat T0:T1   the heartbeat stops changing
  --delay T0:T1:MS           every answer is late by MS milliseconds (server role)
  --spike T                  the counters read a million ticks off for 30 ms

Writes a JSON summary to --out when the dataset ends (plus --linger seconds) or on SIGTERM.
Run with /usr/bin/python3 (the Debian interpreter that has pymodbus).
"""

import argparse
import asyncio
import bisect
import json
import logging
import math
import os
import signal
import sys
import threading
import time

from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
from pymodbus.server import StartAsyncTcpServer
from pymodbus.client import ModbusTcpClient

logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


def read_csv(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            rows.append(line.strip().split(","))
    return rows


def read_tum(path):
    poses = []
    with open(path) as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = [float(x) for x in line.split()]
            yaw = 2.0 * math.atan2(v[6], v[7])
            poses.append((round(v[0] * 1e9), v[1] * 1000.0, v[2] * 1000.0, yaw))
    return poses


class Dataset:
    def __init__(self, directory):
        self.encoders = [tuple(int(x) for x in r) for r in read_csv(os.path.join(directory, "encoders/data.csv"))]
        frames = read_csv(os.path.join(directory, "cam0/data.csv"))
        self.origin = min(self.encoders[0][0], int(frames[0][0]))
        self.end = max(self.encoders[-1][0], int(frames[-1][0]))
        gt = os.path.join(directory, "groundtruth/data.tum")
        self.truth = read_tum(gt) if os.path.exists(gt) else None
        self.truth_times = [p[0] for p in self.truth] if self.truth else None

    def ticks_at(self, ns):
        """The latest sample at or before ns (the first one before the start)."""
        i = bisect.bisect_right(self.encoders, (ns, 2**40)) - 1
        return self.encoders[max(i, 0)]

    def truth_at(self, ns):
        """(x_mm, y_mm, yaw, speed_mm_per_s) interpolated, or None outside."""
        if not self.truth or ns < self.truth_times[0] or ns > self.truth_times[-1]:
            return None
        i = min(max(bisect.bisect_left(self.truth_times, ns), 1), len(self.truth) - 1)
        (t0, x0, y0, a0), (t1, x1, y1, a1) = self.truth[i - 1], self.truth[i]
        f = (ns - t0) / (t1 - t0)
        speed = math.hypot(x1 - x0, y1 - y0) / ((t1 - t0) * 1e-9)
        da = math.atan2(math.sin(a1 - a0), math.cos(a1 - a0))
        return x0 + f * (x1 - x0), y0 + f * (y1 - y0), a0 + f * da, speed


def words32(value, low_first):
    u = value & 0xFFFFFFFF
    hi, lo = u >> 16, u & 0xFFFF
    return [lo, hi] if low_first else [hi, lo]


def int32(words, low_first):
    hi, lo = (words[1], words[0]) if low_first else (words[0], words[1])
    u = (hi << 16) | lo
    return u - (1 << 32) if u & 0x80000000 else u


class Plc:
    def __init__(self, args):
        self.args = args
        self.data = Dataset(args.dataset)
        self.low_first = args.word_order == "low_first"
        wall_now = time.time()
        self.start = time.monotonic() + ((args.start_unix - wall_now) if args.start_unix > 0 else 0.0)
        self.heartbeat = 0
        self.request = 0
        self.relocalize = 0
        self.request_time = None
        self.answered_request = 0
        self.fixes = []
        self.answers_ms = []
        self.requests_sent = 0
        self.lock = threading.Lock()
        self.freeze = [float(x) for x in args.freeze_heartbeat.split(":")] if args.freeze_heartbeat else None
        self.delay = [float(x) for x in args.delay.split(":")] if args.delay else None
        self.spike = args.spike

    def dataset_ns(self, monotonic):
        return self.data.origin + round((monotonic - self.start) * 1e9)

    def dataset_s(self, monotonic):
        return (self.dataset_ns(monotonic) - self.data.origin) * 1e-9

    def inputs(self, now):
        """The input registers at monotonic time now: 0-6, and 7-11 for four counters."""
        ns = self.dataset_ns(now)
        counters = list(self.data.ticks_at(ns)[1:])
        t = self.dataset_s(now)
        if self.spike is not None and self.spike <= t < self.spike + 0.03:
            counters = [c + 1000000 for c in counters]
        words = words32(counters[0], self.low_first) + words32(counters[1], self.low_first) + [
            self.heartbeat & 0xFFFF, self.request & 0xFFFF, self.relocalize & 0xFFFF]
        if len(counters) == 4:  # a mecanum vehicle's rear wheels
            words += [0] + words32(counters[2], self.low_first) + words32(counters[3], self.low_first)
        return words

    def tick(self, now):
        """One PLC cycle (10 ms): heartbeat and fix requests."""
        t = self.dataset_s(now)
        if not (self.freeze and self.freeze[0] <= t < self.freeze[1]):
            self.heartbeat += 1
        if self.args.relocalize_at is not None and t >= self.args.relocalize_at and self.relocalize == 0:
            self.relocalize = 1  # the vehicle's pose is unknown: mosaicloc must relocalize
        if self.args.request_period_ms > 0 and now >= self.next_request:
            self.request += 1
            self.requests_sent += 1
            self.request_time = now
            self.next_request += self.args.request_period_ms * 1e-3

    def receive(self, words, now):
        """The eleven fix registers 100-110 as written by (or read from) mosaicloc."""
        fix = {
            "t_s": self.dataset_s(now),
            "x_mm": int32(words[0:2], self.low_first) * 0.01,
            "y_mm": int32(words[2:4], self.low_first) * 0.01,
            "yaw_rad": int32(words[4:6], self.low_first) * 1e-6,
            "status": words[6],
            "quality": words[7],
            "echo": words[8],
            "heartbeat": words[9],
            "mode": words[10],
        }
        with self.lock:
            if self.request_time is not None and fix["echo"] == (self.request & 0xFFFF) and \
                    self.answered_request != self.request:
                self.answered_request = self.request
                self.answers_ms.append((now - self.request_time) * 1000.0)
            truth = self.data.truth_at(self.dataset_ns(now))
            before = self.data.truth_at(self.dataset_ns(now) - 300_000_000)
            if truth:
                fix["error_mm"] = math.hypot(fix["x_mm"] - truth[0], fix["y_mm"] - truth[1])
                fix["speed_mps"] = truth[3] * 1e-3
                # Standing still for the last 0.3 s: the answer's time stamp does not matter.
                fix["still"] = truth[3] < 1.0 and before is not None and before[3] < 1.0
            self.fixes.append(fix)

    def finished(self, now):
        return self.dataset_ns(now) > self.data.end + self.args.linger * 1e9

    def summary(self):
        with self.lock:
            fixes = list(self.fixes)
            answers = sorted(self.answers_ms)
        errors = [f for f in fixes if "error_mm" in f and f["status"] in (1, 2)]
        still = [f["error_mm"] for f in errors if f["still"]]
        moving = [f for f in errors if f["speed_mps"] >= 0.05]
        out = {
            "fixes_received": len(fixes),
            "status_counts": [sum(1 for f in fixes if f["status"] == s) for s in range(5)],
            "mode_counts": [sum(1 for f in fixes if f["mode"] == m) for m in range(5)],
            "requests": self.requests_sent,
            "relocalize_requests": self.relocalize,
            "answered": len(answers),
            "answer_p50_ms": answers[len(answers) // 2] if answers else None,
            "answer_max_ms": answers[-1] if answers else None,
            "still_fixes": len(still),
            "still_max_error_mm": max(still) if still else None,
            "moving_fixes": len(moving),
            "moving_max_error_mm": max(f["error_mm"] for f in moving) if moving else None,
            # The error a fix may have while moving: its time stamp is good to a few ms.
            "moving_max_error_per_speed_ms": max(f["error_mm"] / f["speed_mps"] for f in moving) if moving else None,
            "moving_rms_error_mm": math.sqrt(sum(f["error_mm"] ** 2 for f in moving) / len(moving)) if moving else None,
            "fixes": fixes,
        }
        return out


def write_summary(plc, path):
    with open(path + ".tmp", "w") as f:
        json.dump(plc.summary(), f, indent=2)
    os.replace(path + ".tmp", path)


class RecordingBlock(ModbusSequentialDataBlock):
    """Holding registers that tell the PLC when mosaicloc writes the fix, and can answer late."""

    def __init__(self, plc):
        super().__init__(0, [0] * 200)
        self.plc = plc

    def getValues(self, address, count=1):  # noqa: N802 (pymodbus' name)
        if self.plc.delay:
            t = self.plc.dataset_s(time.monotonic())
            if self.plc.delay[0] <= t < self.plc.delay[1]:
                time.sleep(self.plc.delay[2] * 1e-3)
        return super().getValues(address, count)

    def setValues(self, address, values):  # noqa: N802
        super().setValues(address, values)
        if address <= 100 < address + len(values):
            self.plc.receive(super().getValues(100, 11), time.monotonic())


async def serve(plc, args):
    block = RecordingBlock(plc)
    context = ModbusServerContext(slaves=ModbusSlaveContext(hr=block, zero_mode=True), single=True)
    # A PLC restarted on its port must bind it again while the killed one's connections are
    # still in TIME_WAIT (pymodbus does not set SO_REUSEADDR by default; PLCs do).
    server = await StartAsyncTcpServer(context=context, address=("127.0.0.1", args.port), defer_start=True,
                                       allow_reuse_address=True)
    task = asyncio.create_task(server.serve_forever())

    def served(done):  # a server that stops by itself (it could not listen, say) is a failure
        if not done.cancelled() and done.exception() is not None:
            print(f"pymodbus PLC: serving on port {args.port} failed: {done.exception()!r}", file=sys.stderr)
            os._exit(3)

    task.add_done_callback(served)
    plc.next_request = plc.start + args.request_period_ms * 1e-3
    stop = asyncio.Event()
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, stop.set)
    while not stop.is_set() and not plc.finished(time.monotonic()):
        now = time.monotonic()
        plc.tick(now)
        ModbusSequentialDataBlock.setValues(block, 0, plc.inputs(now))
        try:
            await asyncio.wait_for(stop.wait(), 0.01)
        except asyncio.TimeoutError:
            pass
    write_summary(plc, args.out)
    await server.shutdown()
    task.cancel()


def play_as_client(plc, args):
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    client = ModbusTcpClient("127.0.0.1", port=args.port, timeout=1)
    plc.next_request = plc.start + args.request_period_ms * 1e-3
    last_heartbeat = None
    while not stop.is_set() and not plc.finished(time.monotonic()):
        now = time.monotonic()
        plc.tick(now)
        try:
            client.write_registers(0, plc.inputs(now), slave=1)
            r = client.read_holding_registers(100, 11, slave=1)
            if not r.isError() and r.registers[9] != last_heartbeat:
                last_heartbeat = r.registers[9]
                plc.receive(r.registers, time.monotonic())
        except Exception:  # mosaicloc not up yet: try again next cycle
            client.close()
        stop.wait(0.01)
    client.close()
    write_summary(plc, args.out)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", required=True)
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--role", choices=["server", "client"], default="server")
    parser.add_argument("--start-unix", type=float, default=0.0)
    parser.add_argument("--request-period-ms", type=float, default=200.0)
    parser.add_argument("--word-order", choices=["high_first", "low_first"], default="high_first")
    parser.add_argument("--linger", type=float, default=0.5)
    parser.add_argument("--freeze-heartbeat")
    parser.add_argument("--delay")
    parser.add_argument("--spike", type=float)
    parser.add_argument("--relocalize-at", type=float, help="dataset seconds: ask mosaicloc to relocalize")
    parser.add_argument("--out", required=True)
    args = parser.parse_args()
    plc = Plc(args)
    if args.role == "server":
        asyncio.run(serve(plc, args))
    else:
        play_as_client(plc, args)


if __name__ == "__main__":
    sys.exit(main())
