"""The check both rosbags oracles run (rosbags_oracle.py, rosbags_actions.py): for each case
{"type", "hash", "cdr" (hex, or null for a hash alone), "values"} the hash against rosbags',
the bytes decoded into the values, and re-encoded into the same bytes. Prints one line per
case, `<type> <rosbags' hash>: ok` or the disagreements; returns whether any disagreed."""

import dataclasses


def plain(store, v):
    """A decoded message as JSON-like values (constants left out)."""
    if dataclasses.is_dataclass(v):
        names = [name for name, _ in store.fielddefs[v.__msgtype__][1]]
        return {n: plain(store, getattr(v, n)) for n in names}
    if hasattr(v, "tolist"):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [plain(store, x) for x in v]
    return v


def check(store, cases):
    failed = False
    for case in cases:
        ty = case["type"]
        problems = []
        want = store.hash_rihs01(ty)
        if case["hash"] != want:
            problems.append(f"hash {case['hash']} != rosbags {want}")
        if case.get("cdr") is not None:
            data = bytes.fromhex(case["cdr"])
            try:
                msg = store.deserialize_cdr(data, ty)
                got = plain(store, msg)
                if got != case["values"]:
                    problems.append(f"decoded {got} != {case['values']}")
                again = bytes(store.serialize_cdr(msg, ty))
                if again != data:
                    problems.append(f"rosbags encodes {again.hex()} != {data.hex()}")
            except Exception as e:  # noqa: BLE001 - any failure to decode is a disagreement
                problems.append(f"decode: {e!r}")
        print(f"{ty} {want}: {'ok' if not problems else '; '.join(problems)}")
        failed |= bool(problems)
    return failed
