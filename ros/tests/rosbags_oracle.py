"""The outside oracle for gelgrip-ros: rosbags (PyPI) computes the REP-2016 hashes of ROS 2's
own message definitions and (de)serialises CDR. Reads the Rust side's cases as JSON on stdin:
[{"type": "pkg/msg/Name", "hash": "RIHS01_...", "cdr": "<hex>", "values": {...}}, ...];
registers gelgrip_msgs from the .msg files in argv[1]; for each case checks the hash, decodes
the bytes into the values, and re-encodes them into the same bytes. Prints one line per case;
exits 1 on the first disagreement."""

import dataclasses
import json
import pathlib
import sys

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

store = get_typestore(Stores.ROS2_JAZZY)
msg_dir = pathlib.Path(sys.argv[1])
types = {}
for f in sorted(msg_dir.glob("*.msg")):
    types.update(get_types_from_msg(f.read_text(), f"gelgrip_msgs/msg/{f.stem}"))
store.register(types)


def plain(v):
    """A decoded message as JSON-like values."""
    if dataclasses.is_dataclass(v):
        # The type's declared fields: constants (DiagnosticStatus.OK, ...) are left out.
        names = [name for name, _ in store.fielddefs[v.__msgtype__][1]]
        return {n: plain(getattr(v, n)) for n in names}
    if hasattr(v, "tolist"):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


failed = False
for case in json.load(sys.stdin):
    ty = case["type"]
    want_hash = store.hash_rihs01(ty)
    data = bytes.fromhex(case["cdr"])
    problems = []
    if case["hash"] != want_hash:
        problems.append(f"hash {case['hash']} != rosbags {want_hash}")
    try:
        msg = store.deserialize_cdr(data, ty)
        got = plain(msg)
        if got != case["values"]:
            problems.append(f"decoded {got} != {case['values']}")
        again = bytes(store.serialize_cdr(msg, ty))
        if again != data:
            problems.append(f"rosbags encodes {again.hex()} != {data.hex()}")
    except Exception as e:  # noqa: BLE001 - any failure to decode is a disagreement
        problems.append(f"decode: {e!r}")
    print(f"{ty}: {'ok' if not problems else '; '.join(problems)}")
    failed |= bool(problems)
sys.exit(1 if failed else 0)
