use super::*;

#[test]
fn the_command_message_hashes_as_rosidl_generates_it() {
    // control_msgs' generated gripper_command__description.c (msg/GripperCommand).
    assert_eq!(
        GRIPPER_COMMAND_MSG.rihs01(),
        "RIHS01_57eb8f326c9889ca8bb34ead82cc94cc09bf6bc5c3b6c09546dca3a00b589890"
    );
}

#[test]
fn dds_names_follow_rmw_zenoh() {
    assert_eq!(
        SEND_GOAL.dds_name(),
        "control_msgs::action::dds_::GripperCommand_SendGoal_"
    );
    assert_eq!(
        CANCEL_GOAL.dds_name(),
        "action_msgs::srv::dds_::CancelGoal_"
    );
    assert_eq!(
        FEEDBACK_MESSAGE.dds_name(),
        "control_msgs::action::dds_::GripperCommand_FeedbackMessage_"
    );
    assert_eq!(
        GOAL_STATUS_ARRAY.dds_name(),
        "action_msgs::msg::dds_::GoalStatusArray_"
    );
}

fn send_goal_bytes(position: f64, effort: f64) -> Vec<u8> {
    let mut w = CdrWriter::default();
    for b in 1..=16u8 {
        w.u8(b);
    }
    w.f64(position);
    w.f64(effort);
    w.into_bytes()
}

#[test]
fn send_goal_requests_decode_and_bad_ones_are_errors() {
    let b = send_goal_bytes(0.0, 5.0);
    assert_eq!(b.len(), 4 + 16 + 16);
    let r = decode_send_goal(&b).expect("decodes");
    assert_eq!(r.goal_id[0], 1);
    assert_eq!(r.goal_id[15], 16);
    assert_eq!(r.max_effort, 5.0);
    // Every truncation is an error, none a panic.
    for n in 0..b.len() {
        assert!(decode_send_goal(&b[..n]).is_err(), "{n} bytes");
    }
    // NaN decodes (the server refuses it, not the decoder).
    assert!(decode_send_goal(&send_goal_bytes(0.0, f64::NAN)).is_ok_and(|r| r.max_effort.is_nan()));
    let mut be = b.clone();
    be[1] = 0;
    assert_eq!(decode_send_goal(&be), Err(CdrError::Encapsulation(0, 0)));
}

#[test]
fn cancel_and_result_requests_decode() {
    let mut w = CdrWriter::default();
    for b in 0..16u8 {
        w.u8(b);
    }
    w.i32(7);
    w.u32(9);
    let b = w.into_bytes();
    let info = decode_cancel_goal(&b).expect("decodes");
    assert_eq!(info.stamp, Time { sec: 7, nanosec: 9 });
    assert_eq!(decode_get_result(&b[..20]).map(|id| id[3]), Ok(3));
    assert!(decode_cancel_goal(&b[..22]).is_err());
    assert!(decode_get_result(&b[..19]).is_err());
}

#[test]
fn responses_encode_in_field_order() {
    let r = GetResultResponse {
        status: GoalStatusCode::Succeeded,
        result: GripperState {
            position_rad: 0.5,
            effort_n: 2.0,
            stalled: false,
            reached_goal: true,
        },
    }
    .to_cdr();
    // header, int8, pad to 8, two f64, two bools
    assert_eq!(r.len(), 4 + 8 + 16 + 2);
    assert_eq!(r[4], 4);
    assert_eq!(r[r.len() - 1], 1);
    let s = GoalStatusArray {
        status_list: vec![(GoalInfo::default(), GoalStatusCode::Aborted)],
    }
    .to_cdr();
    assert_eq!(s.len(), 4 + 4 + 16 + 8 + 1);
    assert_eq!(s[s.len() - 1], 6);
}
