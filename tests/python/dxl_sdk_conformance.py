#!/usr/bin/env python3
"""Protocol 2.0 conformance of a servo bus, checked with ROBOTIS's own client.

Drives a bus of XM430-W350 servos (the gelgrip emulator, or real ones) through the PyPI
``dynamixel-sdk`` (4.1.0): ping and broadcast ping, single-register reads and writes, the
EEPROM lock, an out-of-range read, GroupSyncWrite/GroupSyncRead with motion towards a goal
over wall-clock time, GroupBulkRead and GroupBulkWrite with a different register per servo,
and reboot (RAM reset, EEPROM kept).

Usage: dxl_sdk_conformance.py PORT [--baud 1000000] [--ids 1,2,3]

Prints one JSON summary on stdout. Exit 0 when every check passed; 1 with a message on
stderr naming the failed check; 3 when the SDK is not installed for this interpreter.
"""

import argparse
import json
import sys
import time

try:
    import dynamixel_sdk as dxl
except ImportError as e:  # a missing SDK is a loud failure, never a pass
    print(
        f"dynamixel_sdk is not importable by {sys.executable} ({e}). Run scripts/test, which "
        "creates target/pyenv with dynamixel-sdk==4.1.0, or pip install dynamixel-sdk==4.1.0.",
        file=sys.stderr,
    )
    sys.exit(3)

MODEL_XM430_W350 = 1020
ACCESS_ERROR = 0x07
ERROR_NUMBER_MASK = 0x7F

# Control table addresses (XM430-W350, Protocol 2.0).
OPERATING_MODE = 11
MAX_POSITION_LIMIT = 48
TORQUE_ENABLE = 64
LED = 65
HARDWARE_ERROR_STATUS = 70
GOAL_CURRENT = 102
PROFILE_VELOCITY = 112
GOAL_POSITION = 116
PRESENT_POSITION = 132
PRESENT_TEMPERATURE = 146
PAST_THE_TABLE = 700  # the table ends at 661

MOVE_PULSES = 1024  # a quarter turn
MOVE_TIMEOUT_S = 4.0
POSITION_TOLERANCE_PULSES = 20


class CheckFailed(Exception):
    """A conformance check did not hold."""


def expect(cond, message):
    if not cond:
        raise CheckFailed(message)


class Bus:
    """The SDK's port and packet handler, with results checked."""

    def __init__(self, port_path, baud):
        self.port = dxl.PortHandler(port_path)
        self.ph = dxl.PacketHandler(2.0)
        expect(self.port.openPort(), f"cannot open {port_path}")
        expect(self.port.setBaudRate(baud), f"baud {baud} not accepted")

    def ok(self, what, comm, error):
        expect(
            comm == dxl.COMM_SUCCESS,
            f"{what}: {self.ph.getTxRxResult(comm)} (comm {comm})",
        )
        expect(
            error & ERROR_NUMBER_MASK == 0,
            f"{what}: status error {error:#04x} ({self.ph.getRxPacketError(error)})",
        )

    def read(self, dxl_id, address, length):
        data, comm, error = self.ph.readTxRx(self.port, dxl_id, address, length)
        self.ok(f"read id {dxl_id} addr {address} len {length}", comm, error)
        expect(len(data) == length, f"read id {dxl_id} addr {address}: {len(data)} bytes")
        return int.from_bytes(bytes(data), "little")

    def write(self, dxl_id, address, length, value):
        data = list(value.to_bytes(length, "little", signed=value < 0))
        comm, error = self.ph.writeTxRx(self.port, dxl_id, address, length, data)
        self.ok(f"write id {dxl_id} addr {address}", comm, error)

    def sync_write(self, address, length, values):
        group = dxl.GroupSyncWrite(self.port, self.ph, address, length)
        for dxl_id, value in values.items():
            expect(group.addParam(dxl_id, list(value.to_bytes(length, "little"))), "addParam")
        comm = group.txPacket()
        expect(comm == dxl.COMM_SUCCESS, f"sync write: {self.ph.getTxRxResult(comm)}")

    def sync_read_signed(self, ids, address, length):
        group = dxl.GroupSyncRead(self.port, self.ph, address, length)
        for dxl_id in ids:
            expect(group.addParam(dxl_id), f"sync read addParam {dxl_id}")
        comm = group.txRxPacket()
        expect(comm == dxl.COMM_SUCCESS, f"sync read: {self.ph.getTxRxResult(comm)}")
        out = {}
        for dxl_id in ids:
            expect(group.isAvailable(dxl_id, address, length), f"sync read: no data from {dxl_id}")
            raw = group.getData(dxl_id, address, length)
            out[dxl_id] = int.from_bytes(raw.to_bytes(length, "little"), "little", signed=True)
        return out


def check_ping(bus, ids):
    models = {}
    for dxl_id in ids:
        model, comm, error = bus.ph.ping(bus.port, dxl_id)
        bus.ok(f"ping {dxl_id}", comm, error)
        expect(model == MODEL_XM430_W350, f"ping {dxl_id}: model {model}, expected 1020")
        models[dxl_id] = model
    absent = max(ids) + 1
    _, comm, _ = bus.ph.ping(bus.port, absent)
    expect(comm == dxl.COMM_RX_TIMEOUT, f"ping of absent id {absent}: comm {comm}, expected timeout")
    return {"models": models, "absent_id_times_out": absent}


def check_broadcast_ping(bus, ids):
    found, comm = bus.ph.broadcastPing(bus.port)
    expect(comm == dxl.COMM_SUCCESS, f"broadcastPing: {bus.ph.getTxRxResult(comm)}")
    expect(sorted(found) == sorted(ids), f"broadcastPing found {sorted(found)}, expected {ids}")
    for dxl_id, (model, _fw) in found.items():
        expect(model == MODEL_XM430_W350, f"broadcastPing: id {dxl_id} model {model}")
    return {"found": sorted(found)}


def check_registers(bus, ids):
    dxl_id = ids[0]
    bus.write(dxl_id, TORQUE_ENABLE, 1, 0)
    cases = [(LED, 1, 1), (PROFILE_VELOCITY, 4, 150), (GOAL_POSITION, 4, 2100), (GOAL_CURRENT, 2, 400)]
    for address, length, value in cases:
        bus.write(dxl_id, address, length, value)
        got = bus.read(dxl_id, address, length)
        expect(got == value, f"addr {address}: wrote {value}, read {got}")
    v1, comm, error = bus.ph.read1ByteTxRx(bus.port, dxl_id, LED)
    bus.ok("read1ByteTxRx LED", comm, error)
    v4, comm, error = bus.ph.read4ByteTxRx(bus.port, dxl_id, GOAL_POSITION)
    bus.ok("read4ByteTxRx goal position", comm, error)
    expect((v1, v4) == (1, 2100), f"typed reads gave LED {v1}, goal {v4}")
    bus.write(dxl_id, LED, 1, 0)
    return {"id": dxl_id, "addresses": [c[0] for c in cases]}


def check_errors(bus, ids):
    dxl_id = ids[-1]
    mode = bus.read(dxl_id, OPERATING_MODE, 1)
    bus.write(dxl_id, TORQUE_ENABLE, 1, 1)
    comm, error = bus.ph.write1ByteTxRx(bus.port, dxl_id, OPERATING_MODE, 5)
    expect(comm == dxl.COMM_SUCCESS, f"EEPROM write, torque on: {bus.ph.getTxRxResult(comm)}")
    expect(error & ERROR_NUMBER_MASK == ACCESS_ERROR, f"EEPROM write, torque on: error {error:#04x}")
    eeprom_error = error
    bus.write(dxl_id, TORQUE_ENABLE, 1, 0)
    expect(bus.read(dxl_id, OPERATING_MODE, 1) == mode, "a refused EEPROM write changed the mode")
    data, comm, error = bus.ph.readTxRx(bus.port, dxl_id, PAST_THE_TABLE, 4)
    failed = comm != dxl.COMM_SUCCESS or error & ERROR_NUMBER_MASK != 0
    expect(failed, f"read at {PAST_THE_TABLE} succeeded with {data}")
    return {"eeprom_torque_on_error": eeprom_error, "out_of_range_read_error": error, "comm": comm}


def check_sync_motion(bus, ids):
    bus.sync_write(TORQUE_ENABLE, 1, {i: 0 for i in ids})
    start = bus.sync_read_signed(ids, PRESENT_POSITION, 4)
    goal = {i: (start[i] + MOVE_PULSES) % 4096 for i in ids}
    bus.sync_write(PROFILE_VELOCITY, 4, {i: 100 for i in ids})
    bus.sync_write(GOAL_POSITION, 4, goal)
    bus.sync_write(TORQUE_ENABLE, 1, {i: 1 for i in ids})
    samples = []
    t0 = time.monotonic()
    while time.monotonic() - t0 < MOVE_TIMEOUT_S:
        now = bus.sync_read_signed(ids, PRESENT_POSITION, 4)
        samples.append(now)
        if all(abs(now[i] - goal[i]) <= POSITION_TOLERANCE_PULSES for i in ids):
            break
        time.sleep(0.05)
    final = samples[-1]
    for i in ids:
        expect(abs(final[i] - goal[i]) <= POSITION_TOLERANCE_PULSES,
               f"id {i}: at {final[i]} after {MOVE_TIMEOUT_S} s, goal {goal[i]} (start {start[i]})")
        between = {s[i] for s in samples if min(start[i], goal[i]) + POSITION_TOLERANCE_PULSES
                   < s[i] < max(start[i], goal[i]) - POSITION_TOLERANCE_PULSES}
        expect(len(between) >= 2, f"id {i}: no motion seen between start and goal: {samples}")
    elapsed = time.monotonic() - t0
    return {"start": start, "goal": goal, "final": final, "samples": len(samples),
            "seconds": round(elapsed, 3)}


def check_bulk_read(bus, ids):
    plan = [(PRESENT_POSITION, 4), (PRESENT_TEMPERATURE, 1), (HARDWARE_ERROR_STATUS, 1)]
    group = dxl.GroupBulkRead(bus.port, bus.ph)
    for dxl_id, (address, length) in zip(ids, plan):
        expect(group.addParam(dxl_id, address, length), f"bulk read addParam {dxl_id}")
    comm = group.txRxPacket()
    expect(comm == dxl.COMM_SUCCESS, f"bulk read: {bus.ph.getTxRxResult(comm)}")
    got = {}
    for dxl_id, (address, length) in zip(ids, plan):
        expect(group.isAvailable(dxl_id, address, length), f"bulk read: nothing from {dxl_id}")
        got[dxl_id] = group.getData(dxl_id, address, length)
    position = bus.sync_read_signed(ids[:1], PRESENT_POSITION, 4)[ids[0]]
    expect(abs(position - got[ids[0]]) <= POSITION_TOLERANCE_PULSES,
           f"bulk read: position {got[ids[0]]}, a sync read then gave {position}")
    if len(ids) >= 2:
        expect(10 <= got[ids[1]] <= 80, f"bulk read: temperature {got[ids[1]]} °C")
    if len(ids) >= 3:
        expect(got[ids[2]] == 0, f"bulk read: hardware error {got[ids[2]]:#04x}")
    return {"values": got}


def check_bulk_write(bus, ids):
    plan = [(LED, 1, 1), (PROFILE_VELOCITY, 4, 77), (GOAL_CURRENT, 2, 321)]
    group = dxl.GroupBulkWrite(bus.port, bus.ph)
    for dxl_id, (address, length, value) in zip(ids, plan):
        data = list(value.to_bytes(length, "little"))
        expect(group.addParam(dxl_id, address, length, data), f"bulk write addParam {dxl_id}")
    comm = group.txPacket()
    expect(comm == dxl.COMM_SUCCESS, f"bulk write: {bus.ph.getTxRxResult(comm)}")
    for dxl_id, (address, length, value) in zip(ids, plan):
        got = bus.read(dxl_id, address, length)
        expect(got == value, f"bulk write id {dxl_id} addr {address}: wrote {value}, read {got}")
    return {"written": {i: p[0] for i, p in zip(ids, plan)}}


def check_reboot(bus, ids):
    dxl_id = ids[0]
    bus.write(dxl_id, TORQUE_ENABLE, 1, 0)
    bus.write(dxl_id, MAX_POSITION_LIMIT, 4, 4000)
    bus.write(dxl_id, TORQUE_ENABLE, 1, 1)
    bus.write(dxl_id, LED, 1, 1)
    comm, error = bus.ph.reboot(bus.port, dxl_id)
    bus.ok(f"reboot {dxl_id}", comm, error)
    time.sleep(0.1)
    model, comm, error = bus.ph.ping(bus.port, dxl_id)
    bus.ok(f"ping {dxl_id} after reboot", comm, error)
    torque, led = bus.read(dxl_id, TORQUE_ENABLE, 1), bus.read(dxl_id, LED, 1)
    expect((torque, led) == (0, 0), f"after reboot torque {torque}, LED {led}: RAM not reset")
    limit = bus.read(dxl_id, MAX_POSITION_LIMIT, 4)
    expect(limit == 4000, f"after reboot Max Position Limit {limit}: EEPROM not kept")
    return {"id": dxl_id, "model": model}


CHECKS = [
    ("ping", check_ping),
    ("broadcast_ping", check_broadcast_ping),
    ("registers", check_registers),
    ("errors", check_errors),
    ("sync_write_read_motion", check_sync_motion),
    ("bulk_read", check_bulk_read),
    ("bulk_write", check_bulk_write),
    ("reboot", check_reboot),
]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("port")
    ap.add_argument("--baud", type=int, default=1_000_000)
    ap.add_argument("--ids", default="1,2,3")
    args = ap.parse_args()
    ids = [int(i) for i in args.ids.split(",")]
    summary = {"sdk": "dynamixel-sdk", "port": args.port, "baud": args.baud, "ids": ids,
               "checks": {}, "ok": False}
    current = "open"
    try:
        bus = Bus(args.port, args.baud)
        for current, check in CHECKS:
            summary["checks"][current] = check(bus, ids)
        bus.port.closePort()
    except CheckFailed as e:
        summary["failed"] = {"check": current, "reason": str(e)}
        print(json.dumps(summary))
        print(f"conformance check failed: {summary['failed']['check']}: {e}", file=sys.stderr)
        return 1
    summary["ok"] = True
    summary["passed"] = len(CHECKS)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
