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
import sys

from oracle_check import check
from rosbags_actions_types import SEI, command_store

store = command_store(sys.argv[1])
if store.hash_rihs01("service_msgs/msg/ServiceEventInfo") != SEI:
    sys.exit("ServiceEventInfo does not hash as rosidl's: the expansion is wrong")
sys.exit(1 if check(store, json.load(sys.stdin)) else 0)
