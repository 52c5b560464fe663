//! `control_msgs/action/GripperCommand` as rmw_zenoh carries it: an action is three
//! services (`_action/send_goal`, `_action/cancel_goal` from `action_msgs`, `_action/get_result`)
//! and two topics (`_action/feedback`, `_action/status`), each with its own type and
//! REP-2016 hash. Here: those types (with `action_msgs` and `unique_identifier_msgs`), the
//! requests decoded from CDR (bounds-checked: bad bytes are a [`CdrError`]), and the
//! responses, feedback and status encoded.

use crate::catalog::{TIME, one, seq};
use crate::cdr::CdrWriter;
use crate::cdr_read::{CdrError, CdrReader};
use crate::msgs::{Message, Time};
use crate::services::{array, event_fields, service_fields};
use crate::types::{Constant, FieldType as T, MsgType};

/// `unique_identifier_msgs/msg/UUID`.
pub static UUID: MsgType = MsgType {
    name: "unique_identifier_msgs/msg/UUID",
    fields: &[array("uuid", T::Uint8, 16)],
    constants: &[],
};

/// `action_msgs/msg/GoalInfo`.
pub static GOAL_INFO: MsgType = MsgType {
    name: "action_msgs/msg/GoalInfo",
    fields: &[one("goal_id", T::Msg(&UUID)), one("stamp", T::Msg(&TIME))],
    constants: &[],
};

const fn status_constant(name: &'static str, value: &'static str) -> Constant {
    Constant {
        ty: T::Int8,
        name,
        value,
    }
}

/// `action_msgs/msg/GoalStatus`.
pub static GOAL_STATUS: MsgType = MsgType {
    name: "action_msgs/msg/GoalStatus",
    fields: &[one("goal_info", T::Msg(&GOAL_INFO)), one("status", T::Int8)],
    constants: &[
        status_constant("STATUS_UNKNOWN", "0"),
        status_constant("STATUS_ACCEPTED", "1"),
        status_constant("STATUS_EXECUTING", "2"),
        status_constant("STATUS_CANCELING", "3"),
        status_constant("STATUS_SUCCEEDED", "4"),
        status_constant("STATUS_CANCELED", "5"),
        status_constant("STATUS_ABORTED", "6"),
    ],
};

/// `action_msgs/msg/GoalStatusArray` (the `_action/status` topic).
pub static GOAL_STATUS_ARRAY: MsgType = MsgType {
    name: "action_msgs/msg/GoalStatusArray",
    fields: &[seq("status_list", T::Msg(&GOAL_STATUS))],
    constants: &[],
};

/// `action_msgs/srv/CancelGoal_Request`.
pub static CANCEL_GOAL_REQUEST: MsgType = MsgType {
    name: "action_msgs/srv/CancelGoal_Request",
    fields: &[one("goal_info", T::Msg(&GOAL_INFO))],
    constants: &[],
};

/// `action_msgs/srv/CancelGoal_Response`.
pub static CANCEL_GOAL_RESPONSE: MsgType = MsgType {
    name: "action_msgs/srv/CancelGoal_Response",
    fields: &[
        one("return_code", T::Int8),
        seq("goals_canceling", T::Msg(&GOAL_INFO)),
    ],
    constants: &[
        status_constant("ERROR_NONE", "0"),
        status_constant("ERROR_REJECTED", "1"),
        status_constant("ERROR_UNKNOWN_GOAL_ID", "2"),
        status_constant("ERROR_GOAL_TERMINATED", "3"),
    ],
};

/// `action_msgs/srv/CancelGoal_Event`.
pub static CANCEL_GOAL_EVENT: MsgType = MsgType {
    name: "action_msgs/srv/CancelGoal_Event",
    fields: &event_fields(&CANCEL_GOAL_REQUEST, &CANCEL_GOAL_RESPONSE),
    constants: &[],
};

/// `action_msgs/srv/CancelGoal` (the `_action/cancel_goal` service).
pub static CANCEL_GOAL: MsgType = MsgType {
    name: "action_msgs/srv/CancelGoal",
    fields: &service_fields(
        &CANCEL_GOAL_REQUEST,
        &CANCEL_GOAL_RESPONSE,
        &CANCEL_GOAL_EVENT,
    ),
    constants: &[],
};

/// `control_msgs/msg/GripperCommand`.
pub static GRIPPER_COMMAND_MSG: MsgType = MsgType {
    name: "control_msgs/msg/GripperCommand",
    fields: &[one("position", T::Float64), one("max_effort", T::Float64)],
    constants: &[],
};

/// `control_msgs/action/GripperCommand_Goal`.
pub static GOAL: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_Goal",
    fields: &[one("command", T::Msg(&GRIPPER_COMMAND_MSG))],
    constants: &[],
};

const STATE_FIELDS: [crate::types::Field; 4] = [
    one("position", T::Float64),
    one("effort", T::Float64),
    one("stalled", T::Bool),
    one("reached_goal", T::Bool),
];

/// `control_msgs/action/GripperCommand_Result`.
pub static RESULT: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_Result",
    fields: &STATE_FIELDS,
    constants: &[],
};

/// `control_msgs/action/GripperCommand_Feedback`.
pub static FEEDBACK: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_Feedback",
    fields: &STATE_FIELDS,
    constants: &[],
};

/// `control_msgs/action/GripperCommand_SendGoal_Request`.
pub static SEND_GOAL_REQUEST: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_SendGoal_Request",
    fields: &[one("goal_id", T::Msg(&UUID)), one("goal", T::Msg(&GOAL))],
    constants: &[],
};

/// `control_msgs/action/GripperCommand_SendGoal_Response`.
pub static SEND_GOAL_RESPONSE: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_SendGoal_Response",
    fields: &[one("accepted", T::Bool), one("stamp", T::Msg(&TIME))],
    constants: &[],
};

/// `control_msgs/action/GripperCommand_SendGoal_Event`.
pub static SEND_GOAL_EVENT: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_SendGoal_Event",
    fields: &event_fields(&SEND_GOAL_REQUEST, &SEND_GOAL_RESPONSE),
    constants: &[],
};

/// `control_msgs/action/GripperCommand_SendGoal` (the `_action/send_goal` service).
pub static SEND_GOAL: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_SendGoal",
    fields: &service_fields(&SEND_GOAL_REQUEST, &SEND_GOAL_RESPONSE, &SEND_GOAL_EVENT),
    constants: &[],
};

/// `control_msgs/action/GripperCommand_GetResult_Request`.
pub static GET_RESULT_REQUEST: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_GetResult_Request",
    fields: &[one("goal_id", T::Msg(&UUID))],
    constants: &[],
};

/// `control_msgs/action/GripperCommand_GetResult_Response`.
pub static GET_RESULT_RESPONSE: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_GetResult_Response",
    fields: &[one("status", T::Int8), one("result", T::Msg(&RESULT))],
    constants: &[],
};

/// `control_msgs/action/GripperCommand_GetResult_Event`.
pub static GET_RESULT_EVENT: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_GetResult_Event",
    fields: &event_fields(&GET_RESULT_REQUEST, &GET_RESULT_RESPONSE),
    constants: &[],
};

/// `control_msgs/action/GripperCommand_GetResult` (the `_action/get_result` service).
pub static GET_RESULT: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_GetResult",
    fields: &service_fields(&GET_RESULT_REQUEST, &GET_RESULT_RESPONSE, &GET_RESULT_EVENT),
    constants: &[],
};

/// `control_msgs/action/GripperCommand_FeedbackMessage` (the `_action/feedback` topic).
pub static FEEDBACK_MESSAGE: MsgType = MsgType {
    name: "control_msgs/action/GripperCommand_FeedbackMessage",
    fields: &[
        one("goal_id", T::Msg(&UUID)),
        one("feedback", T::Msg(&FEEDBACK)),
    ],
    constants: &[],
};

/// A goal's status (`action_msgs/msg/GoalStatus`'s constants).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i8)]
pub enum GoalStatusCode {
    /// Not known (a result asked for an unknown goal).
    Unknown = 0,
    /// Accepted, not yet executing.
    Accepted = 1,
    /// Executing.
    Executing = 2,
    /// A cancel was accepted; not yet ended.
    Canceling = 3,
    /// Ended as asked.
    Succeeded = 4,
    /// Ended by a cancel.
    Canceled = 5,
    /// Ended otherwise (preempted, stalled, stopped, e-stopped, timed out).
    Aborted = 6,
}

impl GoalStatusCode {
    /// The goal has ended.
    pub fn is_terminal(self) -> bool {
        matches!(self, Self::Succeeded | Self::Canceled | Self::Aborted)
    }

    fn byte(self) -> u8 {
        self as u8
    }
}

/// `action_msgs/srv/CancelGoal_Response`'s return codes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i8)]
pub enum CancelCode {
    /// Canceling the goals listed.
    None = 0,
    /// Refused.
    Rejected = 1,
    /// No such goal.
    UnknownGoalId = 2,
    /// The goal has already ended.
    GoalTerminated = 3,
}

/// A goal's id and when it was accepted (`action_msgs/msg/GoalInfo`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GoalInfo {
    /// The goal's UUID.
    pub goal_id: [u8; 16],
    /// When it was accepted (for a cancel request: cancel the goals accepted at or before).
    pub stamp: Time,
}

impl GoalInfo {
    fn write(&self, w: &mut CdrWriter) {
        for b in self.goal_id {
            w.u8(b);
        }
        w.i32(self.stamp.sec);
        w.u32(self.stamp.nanosec);
    }
}

/// A `SendGoal` request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SendGoalRequest {
    /// The goal's UUID (chosen by the client).
    pub goal_id: [u8; 16],
    /// `command.position`.
    pub position: f64,
    /// `command.max_effort`.
    pub max_effort: f64,
}

/// Decode a `SendGoal` request.
pub fn decode_send_goal(bytes: &[u8]) -> Result<SendGoalRequest, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    Ok(SendGoalRequest {
        goal_id: r.bytes16("goal_id")?,
        position: r.f64("goal.command.position")?,
        max_effort: r.f64("goal.command.max_effort")?,
    })
}

/// Decode a `GetResult` request: the goal's UUID.
pub fn decode_get_result(bytes: &[u8]) -> Result<[u8; 16], CdrError> {
    CdrReader::new(bytes)?.bytes16("goal_id")
}

/// Decode a `CancelGoal` request.
pub fn decode_cancel_goal(bytes: &[u8]) -> Result<GoalInfo, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    Ok(GoalInfo {
        goal_id: r.bytes16("goal_info.goal_id")?,
        stamp: Time {
            sec: r.i32("goal_info.stamp.sec")?,
            nanosec: r.u32("goal_info.stamp.nanosec")?,
        },
    })
}

/// A `SendGoal` response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SendGoalResponse {
    /// Accepted.
    pub accepted: bool,
    /// When.
    pub stamp: Time,
}

impl Message for SendGoalResponse {
    fn msg_type() -> &'static MsgType {
        &SEND_GOAL_RESPONSE
    }

    fn write(&self, w: &mut CdrWriter) {
        w.bool(self.accepted);
        w.i32(self.stamp.sec);
        w.u32(self.stamp.nanosec);
    }
}

/// The gripper's state, as the result and the feedback carry it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct GripperState {
    /// `position`: the fingers' opening, rad (docs/ros.md).
    pub position_rad: f64,
    /// `effort`: the force per finger, N.
    pub effort_n: f64,
    /// `stalled`: the fingers stopped short of the target force.
    pub stalled: bool,
    /// `reached_goal`: the target force was regulated and held.
    pub reached_goal: bool,
}

impl GripperState {
    fn write(&self, w: &mut CdrWriter) {
        w.f64(self.position_rad);
        w.f64(self.effort_n);
        w.bool(self.stalled);
        w.bool(self.reached_goal);
    }
}

/// A `GetResult` response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GetResultResponse {
    /// The goal's final status (`Unknown` for an unknown goal).
    pub status: GoalStatusCode,
    /// The result.
    pub result: GripperState,
}

impl Message for GetResultResponse {
    fn msg_type() -> &'static MsgType {
        &GET_RESULT_RESPONSE
    }

    fn write(&self, w: &mut CdrWriter) {
        w.u8(self.status.byte());
        self.result.write(w);
    }
}

/// A `CancelGoal` response.
#[derive(Debug, Clone, PartialEq)]
pub struct CancelGoalResponse {
    /// What happened.
    pub return_code: CancelCode,
    /// The goals being canceled.
    pub goals_canceling: Vec<GoalInfo>,
}

impl Message for CancelGoalResponse {
    fn msg_type() -> &'static MsgType {
        &CANCEL_GOAL_RESPONSE
    }

    fn write(&self, w: &mut CdrWriter) {
        w.u8(self.return_code as u8);
        w.len(self.goals_canceling.len());
        for g in &self.goals_canceling {
            g.write(w);
        }
    }
}

/// A feedback message.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedbackMessage {
    /// The goal.
    pub goal_id: [u8; 16],
    /// The gripper now.
    pub feedback: GripperState,
}

impl Message for FeedbackMessage {
    fn msg_type() -> &'static MsgType {
        &FEEDBACK_MESSAGE
    }

    fn write(&self, w: &mut CdrWriter) {
        for b in self.goal_id {
            w.u8(b);
        }
        self.feedback.write(w);
    }
}

/// The status topic's message: every goal kept, with its status.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GoalStatusArray {
    /// The goals.
    pub status_list: Vec<(GoalInfo, GoalStatusCode)>,
}

impl Message for GoalStatusArray {
    fn msg_type() -> &'static MsgType {
        &GOAL_STATUS_ARRAY
    }

    fn write(&self, w: &mut CdrWriter) {
        w.len(self.status_list.len());
        for (info, status) in &self.status_list {
            info.write(w);
            w.u8(status.byte());
        }
    }
}

#[cfg(test)]
mod tests;
