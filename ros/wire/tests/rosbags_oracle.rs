//! gelgrip-ros against an outside oracle: the Python `rosbags` package (PyPI) computes each
//! published type's REP-2016 hash from ROS's own definitions (and `gelgrip_msgs`' from the
//! package's `.msg` files), decodes our CDR bytes into the values we encoded, and encodes
//! them back into the same bytes (padding included).
//!
//! The interpreter comes from `GELGRIP_PYTHON`; `scripts/test` makes `target/pyenv` with
//! `rosbags` and runs this test.

use std::io::Write;
use std::process::{Command, Stdio};

use gelgrip_ros_wire::Message;
use gelgrip_ros_wire::msgs::{
    CompressedImage, DepthImage, DiagnosticArray, DiagnosticStatus, Header, JointState, Level,
    SlipCode, TactileContact, TactileContacts, TactileSlip, Time, WrenchStamped,
};
use serde_json::{Value, json};

fn header_json(h: &Header) -> Value {
    json!({"stamp": {"sec": h.stamp.sec, "nanosec": h.stamp.nanosec}, "frame_id": h.frame_id})
}

fn case<M: Message>(m: &M, values: Value) -> Value {
    let hex: String = m.to_cdr().iter().map(|b| format!("{b:02x}")).collect();
    json!({"type": M::msg_type().name, "hash": M::msg_type().rihs01(), "cdr": hex, "values": values})
}

fn cases() -> Vec<Value> {
    let h = Header {
        stamp: Time::from_unix_us(1_764_010_000_250_123),
        frame_id: "f1_tip".into(),
    };
    let joints = JointState {
        header: Header {
            frame_id: String::new(),
            ..h.clone()
        },
        name: vec!["f1".into(), "f2".into(), "f3".into()],
        position_rad: vec![0.5, -1.25, 3.0],
        velocity_rad_s: vec![0.0, 0.125, -2.0],
        effort_nm: vec![0.1, 0.2, 0.3],
    };
    let joints_values = json!({
        "header": header_json(&joints.header), "name": joints.name,
        "position": joints.position_rad, "velocity": joints.velocity_rad_s,
        "effort": joints.effort_nm,
    });
    let jpeg = [0xffu8, 0xd8, 0xff, 0xe0, 1, 2, 3];
    let image = CompressedImage {
        header: h.clone(),
        format: "jpeg",
        data: &jpeg,
    };
    let depth = [0.0f32, 0.00025, 0.0005, 1.5, -0.125, 2.0];
    let depth_image = DepthImage {
        header: h.clone(),
        height: 2,
        width: 3,
        depth_m: &depth,
    };
    let depth_bytes: Vec<u8> = depth.iter().flat_map(|v| v.to_le_bytes()).collect();
    let wrench = WrenchStamped {
        header: h.clone(),
        force_n: [0.0, 0.0, 1.75],
        torque_nm: [0.0; 3],
    };
    let contacts = TactileContacts {
        header: h.clone(),
        contacts: vec![
            TactileContact {
                sensor: "f1_tip".into(),
                in_contact: true,
                area_m2: 2.5e-5,
                max_depth_m: 4e-4,
                mean_depth_m: 1.5e-4,
                centroid_m: [1e-3, -2e-3, 0.0],
                volume_m3: 3.75e-9,
                force_n: 1.25,
            },
            TactileContact {
                sensor: "palm".into(),
                ..TactileContact::default()
            },
        ],
    };
    let contact_json = |c: &TactileContact| {
        json!({"sensor": c.sensor, "in_contact": c.in_contact, "area_m2": c.area_m2,
               "max_depth_m": c.max_depth_m, "mean_depth_m": c.mean_depth_m,
               "centroid": {"x": c.centroid_m[0], "y": c.centroid_m[1], "z": c.centroid_m[2]},
               "volume_m3": c.volume_m3, "force_n": c.force_n})
    };
    let slip = TactileSlip {
        header: h.clone(),
        sensor: vec!["f1_tip".into(), "f1_base".into(), "palm".into()],
        state: vec![SlipCode::Incipient, SlipCode::None, SlipCode::Unknown],
        stick_ratio: vec![0.625, 1.0, 1.0],
        shear_m: vec![[1.5e-4, -2.5e-5, 0.0], [0.0; 3], [0.0; 3]],
        grasp_state: SlipCode::Incipient,
    };
    let slip_values = json!({"header": header_json(&h), "sensor": slip.sensor,
        "state": [2, 1, 0], "stick_ratio": slip.stick_ratio,
        "shear": slip.shear_m.iter().map(|v| json!({"x": v[0], "y": v[1], "z": v[2]}))
            .collect::<Vec<_>>(),
        "grasp_state": 2});
    let diagnostics = DiagnosticArray {
        header: h.clone(),
        status: vec![
            DiagnosticStatus {
                level: Level::Warn,
                name: "gelgrip: sync".into(),
                message: "drops".into(),
                hardware_id: "sim".into(),
                values: vec![
                    ("set_rate_hz".into(), "34.0".into()),
                    ("x".into(), String::new()),
                ],
            },
            DiagnosticStatus {
                level: Level::Ok,
                name: "gelgrip: servos".into(),
                message: String::new(),
                hardware_id: "dxl".into(),
                values: vec![],
            },
        ],
    };
    let status_json = |s: &DiagnosticStatus| {
        json!({"level": s.level as u8, "name": s.name, "message": s.message,
               "hardware_id": s.hardware_id,
               "values": s.values.iter().map(|(k, v)| json!({"key": k, "value": v})).collect::<Vec<_>>()})
    };
    vec![
        case(&joints, joints_values),
        case(
            &image,
            json!({"header": header_json(&h), "format": "jpeg", "data": jpeg}),
        ),
        case(
            &depth_image,
            json!({"header": header_json(&h), "height": 2, "width": 3, "encoding": "32FC1",
                   "is_bigendian": 0, "step": 12, "data": depth_bytes}),
        ),
        case(
            &wrench,
            json!({"header": header_json(&h),
                   "wrench": {"force": {"x": 0.0, "y": 0.0, "z": 1.75},
                              "torque": {"x": 0.0, "y": 0.0, "z": 0.0}}}),
        ),
        case(
            &contacts,
            json!({"header": header_json(&h),
                   "contacts": contacts.contacts.iter().map(contact_json).collect::<Vec<_>>()}),
        ),
        case(&slip, slip_values),
        case(
            &diagnostics,
            json!({"header": header_json(&h),
                   "status": diagnostics.status.iter().map(status_json).collect::<Vec<_>>()}),
        ),
    ]
}

/// Run the oracle `script` (in tests/) with `arg` on `cases`; asserts that it agrees on
/// every case, and returns what it printed.
fn run_oracle(script: &str, arg: &str, cases: &[Value]) -> String {
    let python = std::env::var("GELGRIP_PYTHON").unwrap_or_else(|_| {
        panic!("GELGRIP_PYTHON is not set: run scripts/test, or point it at a python with rosbags")
    });
    let dir = env!("CARGO_MANIFEST_DIR");
    let mut child = Command::new(&python)
        .arg(format!("{dir}/tests/{script}"))
        .arg(format!("{dir}/{arg}"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
    let input = serde_json::to_vec(cases).expect("cases serialise");
    child
        .stdin
        .take()
        .expect("stdin")
        .write_all(&input)
        .expect("writing the cases");
    let out = child.wait_with_output().expect("the oracle ends");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    eprintln!("{stdout}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "rosbags disagrees:\n{stdout}");
    assert_eq!(
        stdout.lines().filter(|l| l.ends_with(": ok")).count(),
        cases.len()
    );
    stdout
}

#[test]
#[ignore = "needs the PyPI rosbags: run scripts/test"]
fn rosbags_agrees_on_hashes_and_cdr_bytes() {
    run_oracle("rosbags_oracle.py", "../gelgrip_msgs/msg", &cases());
}

/// The command side's cases: every service and topic type of the action and the Trigger
/// services by hash, and the CDR of each request a client sends (built here as a client
/// would), each response, the feedback and the status, decoded by rosbags.
fn command_cases() -> Vec<Value> {
    use gelgrip_ros_wire::actions::{
        self, CancelCode, CancelGoalResponse, FeedbackMessage, GetResultResponse, GoalInfo,
        GoalStatusArray, GoalStatusCode, GripperState, SendGoalResponse,
    };
    use gelgrip_ros_wire::cdr::CdrWriter;
    use gelgrip_ros_wire::services::{self, TriggerResponse};
    let hex = |b: &[u8]| b.iter().map(|b| format!("{b:02x}")).collect::<String>();
    let hash_only = |t: &gelgrip_ros_wire::MsgType| json!({"type": t.name, "hash": t.rihs01()});
    let with_cdr = |t: &gelgrip_ros_wire::MsgType, cdr: &[u8], values: Value| json!({"type": t.name, "hash": t.rihs01(), "cdr": hex(cdr), "values": values});
    let id: [u8; 16] = std::array::from_fn(|i| u8::try_from(i * 7 + 1).unwrap_or(0));
    let stamp = Time {
        sec: 1_764_010_000,
        nanosec: 250_000_000,
    };
    let stamp_json = json!({"sec": stamp.sec, "nanosec": stamp.nanosec});
    let state = GripperState {
        position_rad: 0.375,
        effort_n: 4.5,
        stalled: true,
        reached_goal: false,
    };
    let state_json =
        json!({"position": 0.375, "effort": 4.5, "stalled": true, "reached_goal": false});
    let mut send_goal = CdrWriter::default();
    id.iter().for_each(|&b| send_goal.u8(b));
    send_goal.f64(0.0);
    send_goal.f64(5.0);
    let mut cancel = CdrWriter::default();
    id.iter().for_each(|&b| cancel.u8(b));
    cancel.i32(stamp.sec);
    cancel.u32(stamp.nanosec);
    let mut get_result = CdrWriter::default();
    id.iter().for_each(|&b| get_result.u8(b));
    let mut trigger = CdrWriter::default();
    trigger.u8(0);
    let info = GoalInfo { goal_id: id, stamp };
    let info_json = json!({"goal_id": {"uuid": id}, "stamp": stamp_json});
    vec![
        hash_only(&services::TRIGGER),
        hash_only(&actions::CANCEL_GOAL),
        hash_only(&actions::SEND_GOAL),
        hash_only(&actions::GET_RESULT),
        with_cdr(
            &actions::SEND_GOAL_REQUEST,
            &send_goal.into_bytes(),
            json!({"goal_id": {"uuid": id},
                   "goal": {"command": {"position": 0.0, "max_effort": 5.0}}}),
        ),
        with_cdr(
            &actions::SEND_GOAL_RESPONSE,
            &SendGoalResponse {
                accepted: true,
                stamp,
            }
            .to_cdr(),
            json!({"accepted": true, "stamp": stamp_json}),
        ),
        with_cdr(
            &actions::GET_RESULT_REQUEST,
            &get_result.into_bytes(),
            json!({"goal_id": {"uuid": id}}),
        ),
        with_cdr(
            &actions::GET_RESULT_RESPONSE,
            &GetResultResponse {
                status: GoalStatusCode::Aborted,
                result: state,
            }
            .to_cdr(),
            json!({"status": 6, "result": state_json}),
        ),
        with_cdr(
            &actions::CANCEL_GOAL_REQUEST,
            &cancel.into_bytes(),
            json!({"goal_info": info_json}),
        ),
        with_cdr(
            &actions::CANCEL_GOAL_RESPONSE,
            &CancelGoalResponse {
                return_code: CancelCode::None,
                goals_canceling: vec![info, GoalInfo::default()],
            }
            .to_cdr(),
            json!({"return_code": 0, "goals_canceling": [info_json,
                   {"goal_id": {"uuid": ([0u8; 16])}, "stamp": {"sec": 0, "nanosec": 0}}]}),
        ),
        with_cdr(
            &actions::FEEDBACK_MESSAGE,
            &FeedbackMessage {
                goal_id: id,
                feedback: state,
            }
            .to_cdr(),
            json!({"goal_id": {"uuid": id}, "feedback": state_json}),
        ),
        with_cdr(
            &actions::GOAL_STATUS_ARRAY,
            &GoalStatusArray {
                status_list: vec![(info, GoalStatusCode::Executing)],
            }
            .to_cdr(),
            json!({"status_list": [{"goal_info": info_json, "status": 2}]}),
        ),
        with_cdr(
            &services::TRIGGER_REQUEST,
            &trigger.into_bytes(),
            json!({"structure_needs_at_least_one_member": 0}),
        ),
        with_cdr(
            &services::TRIGGER_RESPONSE,
            &TriggerResponse {
                success: false,
                message: "estop: holding".into(),
            }
            .to_cdr(),
            json!({"success": false, "message": "estop: holding"}),
        ),
    ]
}

#[test]
#[ignore = "needs the PyPI rosbags: run scripts/test"]
fn rosbags_agrees_on_the_command_types() {
    run_oracle("rosbags_actions.py", "tests/upstream", &command_cases());
}
