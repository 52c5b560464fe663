"""A ROS 2 action and service client over Zenoh in rmw_zenoh's wire format, for
tests/ros_commands.rs (no ROS install: eclipse-zenoh and rosbags from PyPI).

    python ros_commands_client.py PORT UPSTREAM_DIR NS SCENARIO

Opens a Zenoh session in router mode on tcp/127.0.0.1:PORT (multicast scouting off),
prints `ready`, waits for gelgrip's service tokens under NS (`/gelgrip`), then plays
SCENARIO (`commands`: the six cases and the bad inputs against one gelgrip run; `readonly`:
checks nothing answers) and prints one JSON summary line.

Requests are CDR built by rosbags' serializer (types registered from UPSTREAM_DIR as
ros/wire/tests/rosbags_actions.py does) and carry rmw_zenoh's 33-byte attachment (sequence
number, source timestamp, GID); each service key is
`0/<service>/<DDS type>/<RIHS01 hash>`, the hash read from gelgrip's liveliness token and
checked against rosbags'.
"""

import json
import os
import struct
import sys
import threading
import time
import uuid

import numpy as np
import zenoh

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "../../ros/wire/tests"))
from rosbags_actions_types import command_store  # noqa: E402

port, upstream, ns, scenario = int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4]
store = command_store(upstream)
A = "control_msgs/action/GripperCommand"
NSK = ns.strip("/")

conf = zenoh.Config()
conf.insert_json5("mode", '"router"')
conf.insert_json5("listen/endpoints", f'["tcp/127.0.0.1:{port}"]')
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
print("ready", flush=True)

CLIENT_GID = uuid.uuid4().bytes
seq = [0]
lock = threading.Lock()
events = []  # (t, kind, value) in order of arrival
t0 = time.monotonic()


def log(kind, value):
    with lock:
        events.append((round(time.monotonic() - t0, 3), kind, value))


def att():
    seq[0] += 1
    return struct.pack("<qqB", seq[0], time.time_ns(), 16) + CLIENT_GID


def plain(v):
    if hasattr(v, "__dataclass_fields__"):
        names = [n for n, _ in store.fielddefs[v.__msgtype__][1]]
        return {n: plain(getattr(v, n)) for n in names}
    if hasattr(v, "tolist"):
        return v.tolist()
    if isinstance(v, (list, tuple)):
        return [plain(x) for x in v]
    return v


def tokens():
    return [str(r.ok.key_expr) for r in session.liveliness().get("@ros2_lv/**", timeout=2.0) if r.ok]


def key_of(name, dds):
    """The data key of service or topic NAME (relative to NS) from gelgrip's token."""
    mangled = ("/" + NSK + "/" + name).replace("/", "%")
    for t in tokens():
        parts = t.split("/")
        if mangled in parts:
            i = parts.index(mangled)
            if parts[i + 1] == dds:
                return f"0/{NSK}/{name}/{dds}/{parts[i + 2]}", parts[i + 2], parts[4]
    return None


def call(key, payload, timeout=5.0, raw=False):
    """Query KEY with PAYLOAD; (reply bytes, attachment ok) or ('error', text) or None."""
    my_seq = seq[0] + 1
    replies = list(session.get(key, payload=payload, attachment=att(), timeout=timeout))
    for r in replies:
        if r.ok is not None:
            a = r.ok.attachment.to_bytes() if r.ok.attachment is not None else b""
            good = len(a) == 33 and struct.unpack("<q", a[:8])[0] == my_seq and a[17:] == CLIENT_GID
            return r.ok.payload.to_bytes(), good
        return "error", r.err.payload.to_string()
    return None


def ser(ty, **fields):
    cls = store.types[ty]
    return bytes(store.serialize_cdr(cls(**fields), ty))


def uuid_msg(b):
    return store.types["unique_identifier_msgs/msg/UUID"](uuid=np.frombuffer(b, dtype=np.uint8))


def time_msg(sec=0, nanosec=0):
    return store.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def send_goal_bytes(goal_id, position, effort):
    cmd = store.types["control_msgs/msg/GripperCommand"](position=position, max_effort=effort)
    goal = store.types[f"{A}_Goal"](command=cmd)
    return ser(f"{A}_SendGoal_Request", goal_id=uuid_msg(goal_id), goal=goal)


keys = {}


def send_goal(goal_id, position, effort, raw=None):
    out = call(keys["send_goal"], raw if raw is not None else send_goal_bytes(goal_id, position, effort))
    if out is None or out[0] == "error":
        return {"reply": out}
    r = store.deserialize_cdr(out[0], f"{A}_SendGoal_Response")
    return {"accepted": bool(r.accepted), "attachment_ok": out[1]}


def get_result(goal_id, timeout=30.0):
    out = call(keys["get_result"], ser(f"{A}_GetResult_Request", goal_id=uuid_msg(goal_id)), timeout)
    if out is None or out[0] == "error":
        return {"reply": out}
    return plain(store.deserialize_cdr(out[0], f"{A}_GetResult_Response"))


def cancel(goal_id, raw=None):
    payload = raw
    if payload is None:
        info = store.types["action_msgs/msg/GoalInfo"](goal_id=uuid_msg(goal_id), stamp=time_msg())
        payload = ser("action_msgs/srv/CancelGoal_Request", goal_info=info)
    out = call(keys["cancel_goal"], payload)
    if out is None or out[0] == "error":
        return {"reply": out}
    return plain(store.deserialize_cdr(out[0], "action_msgs/srv/CancelGoal_Response"))


def trigger(name, raw=None):
    payload = raw if raw is not None else ser("std_srvs/srv/Trigger_Request", structure_needs_at_least_one_member=0)
    out = call(keys[name], payload)
    if out is None or out[0] == "error":
        return {"reply": out}
    return plain(store.deserialize_cdr(out[0], "std_srvs/srv/Trigger_Response"))


def on_feedback(sample):
    m = store.deserialize_cdr(sample.payload.to_bytes(), f"{A}_FeedbackMessage")
    log("feedback", {"goal": bytes(m.goal_id.uuid).hex(), **plain(m.feedback)})


def on_status(sample):
    m = store.deserialize_cdr(sample.payload.to_bytes(), "action_msgs/msg/GoalStatusArray")
    log("status", [[bytes(s.goal_info.goal_id.uuid).hex(), int(s.status)] for s in m.status_list])


def on_joints(sample):
    m = get_joint_state(sample.payload.to_bytes())
    log("joints", {"position": m.position.tolist(), "effort": m.effort.tolist()})


def get_joint_state(b):
    return store.deserialize_cdr(b, "sensor_msgs/msg/JointState")


def feedback_of(gid):
    with lock:
        return [v for _, k, v in events if k == "feedback" and v["goal"] == gid.hex()]


def wait_feedback(gid, pred, timeout):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        fb = feedback_of(gid)
        if fb and pred(fb[-1]):
            return fb[-1]
        time.sleep(0.02)
    return None


def joints_since(t):
    with lock:
        return [v for tt, k, v in events if k == "joints" and tt >= t]


def wait_open(timeout=15.0):
    """Wait until the joints have opened (below 0.1 rad) and stopped moving."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        j = joints_since(now() - 0.3)
        if len(j) > 2:
            first, last = j[0]["position"], j[-1]["position"]
            still = max(abs(a - b) for a, b in zip(first, last)) < 0.002
            if still and max(last) < 0.1:
                return True
        time.sleep(0.05)
    return False


def now():
    return time.monotonic() - t0


def wait_tokens(want, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        ts = tokens()
        if all(any(w in t for t in ts) for w in want):
            return ts
        time.sleep(0.2)
    return tokens()


def done(summary):
    """Print the summary and leave (a session with live subscribers can hang the
    interpreter's exit, so close it and exit at once)."""
    print(json.dumps(summary), flush=True)
    for sub in subs:
        sub.undeclare()
    session.close()
    os._exit(0)


subs = []
summary = {}
if scenario == "readonly":
    node = wait_tokens([f"/NN/%/%{NSK}/gelgrip"])
    time.sleep(1.0)
    ts = tokens()
    summary["tokens"] = [t for t in ts if f"%{NSK}" in t]
    # A goal sent where the action server would be: nothing answers.
    probe = f"0/{NSK}/gripper_cmd/_action/send_goal/control_msgs::action::dds_::GripperCommand_SendGoal_/*"
    summary["send_goal_reply"] = call(probe, send_goal_bytes(b"\x01" * 16, 0.0, 2.0), timeout=2.0) is not None
    done(summary)

services = {
    "send_goal": ("gripper_cmd/_action/send_goal", "control_msgs::action::dds_::GripperCommand_SendGoal_", f"{A}_SendGoal"),
    "cancel_goal": ("gripper_cmd/_action/cancel_goal", "action_msgs::srv::dds_::CancelGoal_", "action_msgs/srv/CancelGoal"),
    "get_result": ("gripper_cmd/_action/get_result", "control_msgs::action::dds_::GripperCommand_GetResult_", f"{A}_GetResult"),
    "release": ("release", "std_srvs::srv::dds_::Trigger_", "std_srvs/srv/Trigger"),
    "stop": ("stop", "std_srvs::srv::dds_::Trigger_", "std_srvs/srv/Trigger"),
    "estop": ("estop", "std_srvs::srv::dds_::Trigger_", "std_srvs/srv/Trigger"),
}
ts = wait_tokens([(f"%{NSK}%" + n.replace("/", "%")) + "/" + d for n, d, _ in services.values()])
summary["hashes"] = {}
for k, (name, dds, ty) in services.items():
    found = key_of(name, dds)
    if found is None:
        summary["missing"] = k
        done(summary)
    keys[k], h, kind = found
    summary["hashes"][k] = {"token": h, "rosbags": store.hash_rihs01(ty), "kind": kind}
for topic, dds, ty in (("gripper_cmd/_action/feedback", "control_msgs::action::dds_::GripperCommand_FeedbackMessage_", f"{A}_FeedbackMessage"),
                       ("gripper_cmd/_action/status", "action_msgs::msg::dds_::GoalStatusArray_", "action_msgs/msg/GoalStatusArray")):
    found = key_of(topic, dds)
    summary["hashes"][topic] = {"token": found and found[1], "rosbags": store.hash_rihs01(ty), "kind": found and found[2]}
subs += [
    session.declare_subscriber(f"0/{NSK}/gripper_cmd/_action/feedback/**", on_feedback),
    session.declare_subscriber(f"0/{NSK}/gripper_cmd/_action/status/**", on_status),
    session.declare_subscriber(f"0/{NSK}/joint_states/**", on_joints),
]

def case_grasp(effort):
    gid = uuid.uuid4().bytes
    t = now()
    acc = send_goal(gid, 0.0, effort)
    res = get_result(gid, timeout=40.0)
    return {"accept": acc, "result": res, "feedback": feedback_of(gid), "t_s": round(now() - t, 2)}


def approaching(f):
    """Closing, well before the tennis ball (the fingers start open at pi rad)."""
    return f["position"] < 3.0


def case_position(opening):
    """A goal whose command.position (an opening, rad) comes before the ball (the fingers
    start open at pi rad and touch it at about 2.78 rad): they stop and hold there, touching
    nothing."""
    gid = uuid.uuid4().bytes
    o = {"accept": send_goal(gid, opening, 2.0)}
    o["result"] = get_result(gid, timeout=15.0)
    t = now()
    time.sleep(0.6)
    o["joints_after"] = [j["position"] for j in joints_since(t + 0.1)]
    return o


if scenario == "latency":
    # One goal after two seconds of steady running (docs/ros.md's latency figure).
    time.sleep(2.0)
    summary["goal"] = send_goal(uuid.uuid4().bytes, 0.0, 2.0)
    time.sleep(1.0)
    done(summary)

if scenario == "stall":
    # First a goal that stops short of the ball at its command.position (the stall goal
    # then closes on from there).
    summary["position"] = case_position(3.0)
    summary["stall"] = case_grasp(float(os.environ.get("STALL_EFFORT_N", "200.0")))
    done(summary)

# The joints flowing first (to see the gripper unaffected).
end = time.monotonic() + 15.0
while not joints_since(0.0) and time.monotonic() < end:
    time.sleep(0.05)

# Bad input: each a rejection or an error reply, the gripper unaffected.
bad = {}
good = send_goal_bytes(b"\x09" * 16, 0.0, 2.0)
bad["truncated_goal"] = send_goal(None, 0, 0, raw=good[:11])
bad["big_endian_goal"] = send_goal(None, 0, 0, raw=b"\x00\x00" + good[2:])
bad["nan_effort"] = send_goal(b"\x0a" * 16, 0.0, float("nan"))
bad["negative_effort"] = send_goal(b"\x0b" * 16, 0.0, -2.0)
bad["huge_effort"] = send_goal(b"\x0c" * 16, 0.0, 1e6)
bad["cancel_unknown"] = cancel(b"\x0d" * 16)
bad["cancel_truncated"] = cancel(None, raw=b"\x00\x01\x00\x00\x01")
bad["result_unknown"] = get_result(b"\x0e" * 16, timeout=5.0)
bad["trigger_empty"] = trigger("stop", raw=b"")
nohash = keys["release"].rsplit("/", 1)[1]
bad["no_such_service"] = call(f"0/{NSK}/no_such_service/std_srvs::srv::dds_::Trigger_/{nohash}",
                              ser("std_srvs/srv/Trigger_Request", structure_needs_at_least_one_member=0), timeout=3.0)
summary["bad"] = bad
time.sleep(0.3)
summary["joints_after_bad"] = joints_since(now() - 0.5)[-1:]



# Cancel mid-grasp (on the approach, before the ball): the fingers hold where they are.
gid = uuid.uuid4().bytes
c = {"accept": send_goal(gid, 0.0, 2.0)}
c["approaching"] = wait_feedback(gid, approaching, 10.0)
c["cancel"] = cancel(gid)
t_cancel = now()
c["result"] = get_result(gid, timeout=10.0)
time.sleep(0.8)
c["joints_after"] = [j["position"] for j in joints_since(t_cancel + 0.2)]
summary["cancel"] = c
summary["release_after_cancel"] = trigger("release")
summary["opened"] = wait_open()
summary["after_release"] = joints_since(now() - 0.3)[-1:]

# A second goal preempts the first on its approach; the second grasps the ball with
# feedback on the way, to reached_goal.
g1, g2 = uuid.uuid4().bytes, uuid.uuid4().bytes
p = {"first": send_goal(g1, 0.0, 2.0)}
p["approaching"] = wait_feedback(g1, approaching, 10.0)
p["second"] = send_goal(g2, 0.0, 2.0)
p["first_result"] = get_result(g1, timeout=10.0)
summary["preempt"] = p
g = {"result": get_result(g2, timeout=40.0), "feedback": feedback_of(g2)}
summary["grasp"] = g

# E-stop mid-squeeze: a harder goal on the held ball, e-stopped while it squeezes.
gid = uuid.uuid4().bytes
e = {"accept": send_goal(gid, 0.0, 4.0)}
e["squeezing"] = wait_feedback(gid, lambda f: f["effort"] > 2.6, 20.0)
t_e = now()
e["estop"] = trigger("estop")
e["result"] = get_result(gid, timeout=10.0)
time.sleep(1.0)
e["joints_before"] = joints_since(t_e - 0.3)[:1]
e["joints_after"] = joints_since(t_e + 0.4)
summary["estop"] = e
with lock:
    summary["statuses"] = [v for _, k, v in events if k == "status"][-1:]
done(summary)
