"""A Zenoh router on loopback that listens to everything gelgrip publishes over rmw_zenoh's
format, for tests/ros_zenoh.rs (no ROS install: eclipse-zenoh and rosbags from PyPI).

    python ros_zenoh_listen.py PORT SECONDS MSG_DIR [HISTORY]

Opens a Zenoh session in router mode listening on tcp/127.0.0.1:PORT (multicast scouting
off), prints `ready` once listening, then subscribes to every key and polls the ROS graph's
liveliness tokens (`@ros2_lv/**`, the largest set seen is kept) until its stdin closes or
SECONDS pass. At the end it prints one JSON object:

  {"tokens": [...],
   "keys": {KEY: {"count": N, "stamps_ns": [...], "arrivals_s": [...],
                  "type": "pkg/msg/Name", "rosbags_hash": "RIHS01_...",
                  "attachments_ok": bool, "sequences_increase": bool,
                  "last": <the last message decoded by rosbags, as JSON>}}}

HISTORY, a comma-separated list of topics without the namespace (`joint_states,tactile/contacts`),
adds to those keys `"history"`: every message received, decoded, in order of arrival.

Each payload is decoded with rosbags' typestore (ROS 2 Jazzy, plus gelgrip_msgs registered
from MSG_DIR's .msg files); `uint8[]` data is given as hex.
"""

import dataclasses
import json
import pathlib
import struct
import sys
import threading
import time

import zenoh
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

port, seconds, msg_dir = int(sys.argv[1]), float(sys.argv[2]), pathlib.Path(sys.argv[3])
history_topics = [t for t in (sys.argv[4] if len(sys.argv) > 4 else "").split(",") if t]

store = get_typestore(Stores.ROS2_JAZZY)
types = {}
for f in sorted(msg_dir.glob("*.msg")):
    types.update(get_types_from_msg(f.read_text(), f"gelgrip_msgs/msg/{f.stem}"))
store.register(types)


def ros_type(dds):
    """`sensor_msgs::msg::dds_::JointState_` -> `sensor_msgs/msg/JointState`."""
    pkg, _, _, name = dds.split("::")
    return f"{pkg}/msg/{name.rstrip('_')}"


def plain(v):
    if dataclasses.is_dataclass(v):
        names = [name for name, _ in store.fielddefs[v.__msgtype__][1]]
        return {n: plain(getattr(v, n)) for n in names}
    if hasattr(v, "tobytes") and getattr(v, "dtype", None) is not None and v.dtype.itemsize == 1:
        return v.tobytes().hex()
    if hasattr(v, "tolist"):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


lock = threading.Lock()
keys = {}
start = time.monotonic()


def keeps_history(key):
    """Whether KEY (`<domain>/<namespace...>/<topic...>/<type>/<hash>`) is a HISTORY topic."""
    topic = "/".join(key.split("/")[1:-2])
    return any(topic.endswith("/" + t) for t in history_topics)


def on_sample(sample):
    key = str(sample.key_expr)
    if key.startswith("@"):
        return
    payload = sample.payload.to_bytes()
    att = sample.attachment.to_bytes() if sample.attachment is not None else b""
    now = time.monotonic() - start
    with lock:
        k = keys.setdefault(
            key,
            {"count": 0, "stamps_ns": [], "arrivals_s": [], "attachments_ok": True,
             "sequences_increase": True, "last_seq": 0, "payload": b"", "errors": [],
             "payloads": [] if keeps_history(key) else None},
        )
        if k["payloads"] is not None:
            k["payloads"].append(payload)
        k["count"] += 1
        k["arrivals_s"].append(now)
        k["payload"] = payload
        if len(att) == 33 and att[16] == 16:
            seq, ts = struct.unpack_from("<qq", att)
            k["stamps_ns"].append(ts)
            if seq <= k["last_seq"]:
                k["sequences_increase"] = False
            k["last_seq"] = seq
        else:
            k["attachments_ok"] = False


config = zenoh.Config()
config.insert_json5("mode", '"router"')
config.insert_json5("listen/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
config.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(config)
sub = session.declare_subscriber("**", on_sample)
print("ready", flush=True)

stdin_closed = threading.Event()


def watch_stdin():
    sys.stdin.read()
    stdin_closed.set()


threading.Thread(target=watch_stdin, daemon=True).start()
tokens = set()
deadline = start + seconds
while time.monotonic() < deadline and not stdin_closed.is_set():
    found = set()
    for reply in session.liveliness().get("@ros2_lv/**", timeout=1.0):
        if reply.ok is not None:
            found.add(str(reply.ok.key_expr))
    if len(found) > len(tokens):
        tokens = found
    time.sleep(0.5)

sub.undeclare()
out = {"tokens": sorted(tokens), "keys": {}}
with lock:
    for key, k in keys.items():
        parts = key.split("/")
        entry = {x: k[x] for x in ("count", "stamps_ns", "arrivals_s", "attachments_ok",
                                   "sequences_increase")}
        try:
            ty = ros_type(parts[-2])
            entry["type"] = ty
            entry["rosbags_hash"] = store.hash_rihs01(ty)
            entry["last"] = plain(store.deserialize_cdr(k["payload"], ty))
            if k["payloads"] is not None:
                entry["history"] = [plain(store.deserialize_cdr(p, ty)) for p in k["payloads"]]
        except Exception as e:  # noqa: BLE001 - reported to the Rust test
            entry["error"] = repr(e)
        out["keys"][key] = entry
session.close()
print(json.dumps(out), flush=True)
