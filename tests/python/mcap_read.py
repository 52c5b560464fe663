"""Reads an MCAP file with the PyPI `mcap` reader and `mcap-ros2-support`'s decoder, for
tests/ros_zenoh.rs: every message must decode. Prints one JSON object:
{"profile": ..., "topics": {TOPIC: {"schema": NAME, "encoding": ..., "count": N,
 "decoded": N, "first_log_ns": T, "last_log_ns": T, "log_equals_stamp": bool,
 "full_velocity": N, "slip_states": {CODE: N}}}, "errors": [...]}, where `full_velocity`
counts the messages with a `velocity` field as long as their `position` (JointState) and
`slip_states` counts each sensor's slip state over the messages with a `grasp_state`
(TactileSlip)."""

import json
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

topics = {}
errors = []
with open(sys.argv[1], "rb") as f:
    reader = make_reader(f, decoder_factories=[DecoderFactory()])
    profile = reader.get_header().profile
    for schema, channel, message, decoded in reader.iter_decoded_messages():
        t = topics.setdefault(
            channel.topic,
            {"schema": schema.name, "encoding": channel.message_encoding, "count": 0,
             "decoded": 0, "first_log_ns": message.log_time, "last_log_ns": 0,
             "log_equals_stamp": True, "full_velocity": 0, "slip_states": {}},
        )
        t["count"] += 1
        t["last_log_ns"] = message.log_time
        if decoded is None:
            errors.append(f"{channel.topic}: undecoded")
            continue
        t["decoded"] += 1
        velocity = getattr(decoded, "velocity", None)
        if velocity is not None and len(velocity) == len(decoded.position) > 0:
            t["full_velocity"] += 1
        if hasattr(decoded, "grasp_state"):
            for code in decoded.state:
                key = str(int(code))
                t["slip_states"][key] = t["slip_states"].get(key, 0) + 1
        stamp = decoded.header.stamp
        if stamp.sec * 1_000_000_000 + stamp.nanosec != message.log_time:
            t["log_equals_stamp"] = False
print(json.dumps({"profile": profile, "topics": topics, "errors": errors}))
