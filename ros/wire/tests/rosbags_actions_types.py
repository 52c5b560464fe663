"""rosbags' typestore with the ROS 2 command types registered: see rosbags_actions.py for
the expansion (rosidl's) and why ServiceEventInfo is registered with `uint8[16]`."""

import pathlib

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

# What rosidl compiled into service_msgs (its generated service_event_info__description.c).
SEI = "RIHS01_41bcbbe07a75c9b52bc96bfd5c24d7f0fc0a08c0cb7921b3373c5732345a6f45"
EVENT_INFO = """uint8 REQUEST_SENT=0
uint8 REQUEST_RECEIVED=1
uint8 RESPONSE_SENT=2
uint8 RESPONSE_RECEIVED=3
uint8 event_type
builtin_interfaces/Time stamp
uint8[16] client_gid
int64 sequence_number
"""


def command_store(upstream_dir):
    """Jazzy's types, the upstream definitions in UPSTREAM_DIR expanded and registered."""
    up = pathlib.Path(upstream_dir)
    store = get_typestore(Stores.EMPTY)
    jazzy = get_typestore(Stores.ROS2_JAZZY).fielddefs
    store.register({k: v for k, v in jazzy.items() if k != "service_msgs/msg/ServiceEventInfo"})
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
        add(pkg, kind, f"{name}_Request",
            request.strip() or "uint8 structure_needs_at_least_one_member")
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
    a = "GripperCommand"
    add("control_msgs", "action", f"{a}_Goal", goal)
    add("control_msgs", "action", f"{a}_Result", result)
    add("control_msgs", "action", f"{a}_Feedback", feedback)
    service("control_msgs", "action", f"{a}_SendGoal",
            f"unique_identifier_msgs/UUID goal_id\n{a}_Goal goal\n",
            "bool accepted\nbuiltin_interfaces/Time stamp\n")
    service("control_msgs", "action", f"{a}_GetResult",
            "unique_identifier_msgs/UUID goal_id\n",
            f"int8 status\n{a}_Result result\n")
    add("control_msgs", "action", f"{a}_FeedbackMessage",
        f"unique_identifier_msgs/UUID goal_id\n{a}_Feedback feedback\n")

    def renamed(v):
        if isinstance(v, str):
            return rename.get(v, v)
        if isinstance(v, tuple):
            return tuple(renamed(x) for x in v)
        if isinstance(v, list):
            return [renamed(x) for x in v]
        return v

    store.register({renamed(k): renamed(v) for k, v in defs.items()})
    return store
