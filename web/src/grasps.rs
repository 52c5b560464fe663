//! The grasp routes: `POST /api/grasp`, which waits for the grasp's outcome, and grasps as
//! goals, `POST /api/grasps` (202 with an id at once) and `GET /api/grasps/{id}`, whose
//! progress `/api/events` carries as `grasp` events. Both go through the one grasp API
//! ([`GripperHandle`]), so a new grasp preempts the running one either way.

use std::time::Duration;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::{Deserialize, Serialize};
use serde_json::json;

use gelgrip_controller::grasp::{GraspRequest, TargetForce};
use gelgrip_controller::grasp_goals::GoalStatus;
use gelgrip_controller::gripper::GripperHandle;

use crate::live::{ExcludedView, FingerView, Snapshot};
use crate::routes::{ApiError, AppState, admit, error, gripper_error, parse};

/// Longest a grasp request may ask to wait, s (the grasp API's bound).
pub const MAX_TIMEOUT_S: f64 = gelgrip_controller::grasp::MAX_TIMEOUT_S;
/// A grasp's timeout when the request names none, s.
pub const DEFAULT_TIMEOUT_S: f64 = 20.0;
/// A grasp's approach speed when the request names none, deg/s.
pub const DEFAULT_SPEED_DEG_S: f64 = 15.0;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GraspBody {
    /// N per finger, or `"auto"`.
    target_force_n: TargetForce,
    speed_deg_s: Option<f64>,
    current_limit_ma: Option<f64>,
    fingers: Option<Vec<String>>,
    timeout_s: Option<f64>,
}

/// Admit the caller, then read the request from `body`.
fn grasp_request(
    s: &AppState,
    headers: &HeaderMap,
    body: &Bytes,
) -> Result<(GripperHandle, GraspRequest), ApiError> {
    let handle = admit(s, headers, false)?;
    let b: GraspBody = parse(body)?;
    let fingers = match &b.fingers {
        None => (0..s.fingers.len()).collect(),
        Some(ids) => {
            let mut out = Vec::new();
            for id in ids {
                match s.fingers.iter().position(|f| f == id) {
                    Some(i) => out.push(i),
                    None => {
                        return Err(ApiError::new(
                            StatusCode::BAD_REQUEST,
                            format!("no finger `{id}`; fingers: {}", s.fingers.join(", ")),
                        ));
                    }
                }
            }
            out
        }
    };
    let timeout_s = b.timeout_s.unwrap_or(DEFAULT_TIMEOUT_S);
    if !(timeout_s.is_finite() && timeout_s > 0.0 && timeout_s <= MAX_TIMEOUT_S) {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            format!("timeout_s = {timeout_s}: expected (0, {MAX_TIMEOUT_S}] s"),
        ));
    }
    let (target_force_n, auto_target) = handle.target(b.target_force_n);
    let request = GraspRequest {
        target_force_n,
        speed_deg_s: b.speed_deg_s.unwrap_or(DEFAULT_SPEED_DEG_S),
        current_limit_ma: b.current_limit_ma.unwrap_or(s.current_limit_ma),
        fingers,
        timeout_s,
        auto_target,
    };
    Ok((handle, request))
}

/// `POST /api/grasp`: start a grasp and answer with its outcome when it ends.
pub(crate) async fn grasp(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    let (handle, request) = match grasp_request(&s, &headers, &body) {
        Ok(r) => r,
        Err(e) => return e.into_response(),
    };
    let timeout_s = request.timeout_s;
    let pending = match handle.start_grasp(request) {
        Ok(p) => p,
        Err(e) => return gripper_error(&e),
    };
    // The grasp resolves by its own timeout; the margin covers a loop that stalls.
    match tokio::time::timeout(Duration::from_secs_f64(timeout_s + 5.0), pending.outcome()).await {
        Ok(Ok(outcome)) => axum::Json(outcome).into_response(),
        Ok(Err(e)) => gripper_error(&e),
        Err(_) => error(
            StatusCode::GATEWAY_TIMEOUT,
            "the grasp did not resolve in time: is the run loop receiving sets?",
        ),
    }
}

/// `POST /api/grasps`: start a grasp as a goal; `202 {"id": N}` at once.
pub(crate) async fn start_goal(
    State(s): State<AppState>,
    headers: HeaderMap,
    body: Bytes,
) -> Response {
    let (handle, request) = match grasp_request(&s, &headers, &body) {
        Ok(r) => r,
        Err(e) => return e.into_response(),
    };
    match s.goals.start(&handle, request) {
        Ok(id) => (
            StatusCode::ACCEPTED,
            [(header::LOCATION, format!("/api/grasps/{id}"))],
            axum::Json(json!({ "id": id })),
        )
            .into_response(),
        Err(e) => gripper_error(&e),
    }
}

/// `GET /api/grasps/{id}`: the goal's state and, once done, its result.
pub(crate) async fn goal(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    let status = id.parse::<u64>().ok().and_then(|n| s.goals.status(n));
    match status {
        Some(g) => axum::Json(g).into_response(),
        None => error(
            StatusCode::NOT_FOUND,
            format!(
                "no grasp goal `{id}`: ids count up from 1 in each run, and the last {} are kept",
                gelgrip_controller::grasp_goals::GraspGoals::KEPT
            ),
        ),
    }
}

/// A goal's progress, as `/api/events` sends it (event `grasp`).
#[derive(Debug, Clone, Serialize)]
pub struct GoalProgress {
    /// The goal.
    #[serde(flatten)]
    pub goal: GoalStatus,
    /// Each finger's phase, force and target now.
    pub fingers: Vec<FingerView>,
    /// Total fused force of the fingers, N.
    pub force_n: f64,
    /// Sensors the gate has left out of the sets meanwhile: their fingers carry on with
    /// their other sensors, or hold.
    pub excluded_sensors: Vec<ExcludedView>,
}

impl GoalProgress {
    /// The newest goal with the fingers of `snapshot`.
    pub fn of(goal: GoalStatus, snapshot: &Snapshot) -> Self {
        Self {
            force_n: snapshot.fingers.iter().map(|f| f.force_n).sum(),
            fingers: snapshot.fingers.clone(),
            excluded_sensors: snapshot.sync.excluded_sensors.clone(),
            goal,
        }
    }
}
