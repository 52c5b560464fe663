"""The outside oracle for gelgrip's ROS 2 commands: rosbags (PyPI) hashes the action's and
the services' types, expanded from the upstream .msg/.srv/.action texts in argv[1]
(tests/upstream/) as rosidl expands them, and (de)serialises the CDR of their requests,
responses and messages.

Expansion (rosidl's): a service `pkg/srv/S` is `S_Request` (the part before `---`; an empty
part is one `uint8 structure_needs_at_least_one_member`), `S_Response`, `S_Event`
(`service_msgs/ServiceEventInfo info`, `S_Request[<=1] request`, `S_Response[<=1] response`)
and the service `S` itself (`request_message`, `response_message`, `event_message`). An
action `pkg/action/A` is `A_Goal`, `A_Result`, `A_Feedback`, the services `A_SendGoal`
(`unique_identifier_msgs/UUID goal_id` + `A_Goal goal` / `bool accepted` +
`builtin_interfaces/Time stamp`) and `A_GetResult` (`UUID goal_id` / `int8 status` +
`A_Result result`), and `A_FeedbackMessage` (`UUID goal_id`, `A_Feedback feedback`).

rosbags 0.11.9 hashes `char` as FIELD_TYPE_CHAR; rosidl maps a .msg `char` to `uint8`
(service_msgs' generated ServiceEventInfo description says FIELD_TYPE_UINT8_ARRAY), so
ServiceEventInfo is registered with `uint8[16] client_gid`; with it rosbags gives the hash
ROS compiles in (RIHS01_41bcbbe0...).

Reads the Rust side's cases as JSON on stdin: [{"type": ..., "hash": ..., "cdr": hex or
null, "values": {...}}]; prints one line per case; exits 1 on the first disagreement."""

import json
import pathlib
import sys

from oracle_check import check
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

# Jazzy's types, ServiceEventInfo left for the rosidl spelling below.
store = get_typestore(Stores.EMPTY)
jazzy = get_typestore(Stores.ROS2_JAZZY).fielddefs
store.register({k: v for k, v in jazzy.items() if k != "service_msgs/msg/ServiceEventInfo"})
up = pathlib.Path(sys.argv[1])
EVENT_INFO = """uint8 REQUEST_SENT=0
uint8 REQUEST_RECEIVED=1
uint8 RESPONSE_SENT=2
uint8 RESPONSE_RECEIVED=3
uint8 event_type
builtin_interfaces/Time stamp
uint8[16] client_gid
int64 sequence_number
"""

# Derived types are parsed as pkg/msg/Name (rosbags' parser knows no other kind), then
# renamed to pkg/srv/Name or pkg/action/Name.
defs = {}
rename = {}


def add(pkg, kind, name, text):
    placeholder = f"{pkg}/msg/{name}"
    if kind != "msg":
        rename[placeholder] = f"{pkg}/{kind}/{name}"
    defs.update(get_types_from_msg(text, placeholder))


def service(pkg, kind, name, request, response):
    add(pkg, kind, f"{name}_Request", request.strip() or "uint8 structure_needs_at_least_one_member")
    add(pkg, kind, f"{name}_Response", response)
    add(pkg, kind, f"{name}_Event",
        f"service_msgs/ServiceEventInfo info\n{name}_Request[<=1] request\n"
        f"{name}_Response[<=1] response\n")
    add(pkg, kind, name,
        f"{name}_Request request_message\n{name}_Response response_message\n"
        f"{name}_Event event_message\n")


defs.update(get_types_from_msg(EVENT_INFO, "service_msgs/msg/ServiceEventInfo"))
add("control_msgs", "msg", "GripperCommand", (up / "GripperCommand.msg").read_text())
for srv, pkg in (("Trigger", "std_srvs"), ("CancelGoal", "action_msgs")):
    req, resp = (up / f"{srv}.srv").read_text().split("---\n")
    service(pkg, "srv", srv, req, resp)
goal, result, feedback = (up / "GripperCommand.action").read_text().split("---\n")
A = "GripperCommand"
add("control_msgs", "action", f"{A}_Goal", goal)
add("control_msgs", "action", f"{A}_Result", result)
add("control_msgs", "action", f"{A}_Feedback", feedback)
service("control_msgs", "action", f"{A}_SendGoal",
        f"unique_identifier_msgs/UUID goal_id\n{A}_Goal goal\n",
        "bool accepted\nbuiltin_interfaces/Time stamp\n")
service("control_msgs", "action", f"{A}_GetResult",
        "unique_identifier_msgs/UUID goal_id\n",
        f"int8 status\n{A}_Result result\n")
add("control_msgs", "action", f"{A}_FeedbackMessage",
    f"unique_identifier_msgs/UUID goal_id\n{A}_Feedback feedback\n")


def renamed(v):
    if isinstance(v, str):
        return rename.get(v, v)
    if isinstance(v, tuple):
        return tuple(renamed(x) for x in v)
    if isinstance(v, list):
        return [renamed(x) for x in v]
    return v


store.register({renamed(k): renamed(v) for k, v in defs.items()})
# What rosidl compiled into service_msgs (its generated service_event_info__description.c).
SEI = "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"
if store.hash_rihs01("service_msgs/msg/ServiceEventInfo") != SEI:
    sys.exit("ServiceEventInfo does not hash as rosidl's: the expansion is wrong")


sys.exit(1 if check(store, json.load(sys.stdin)) else 0)
