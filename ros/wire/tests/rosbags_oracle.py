"""The outside oracle for gelgrip-ros: rosbags (PyPI) computes the REP-2016 hashes of ROS 2's
own message definitions and (de)serialises CDR. Reads the Rust side's cases as JSON on stdin:
[{"type": "pkg/msg/Name", "hash": "RIHS01_...", "cdr": "<hex>", "values": {...}}, ...];
registers gelgrip_msgs from the .msg files in argv[1]; for each case checks the hash, decodes
the bytes into the values, and re-encodes them into the same bytes. Prints one line per case;
exits 1 on the first disagreement."""

import json
import pathlib
import sys

from oracle_check import check
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

store = get_typestore(Stores.ROS2_JAZZY)
msg_dir = pathlib.Path(sys.argv[1])
types = {}
for f in sorted(msg_dir.glob("*.msg")):
    types.update(get_types_from_msg(f.read_text(), f"gelgrip_msgs/msg/{f.stem}"))
store.register(types)


sys.exit(1 if check(store, json.load(sys.stdin)) else 0)
