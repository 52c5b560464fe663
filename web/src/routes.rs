//! The routes: the page and its assets, `GET /api/state`, `GET /api/history`,
//! `GET /api/events` (SSE, 20 Hz, the history first), per-sensor MJPEG, depth and contact
//! PNG, and the command endpoints (the grasp ones are in [`crate::grasps`]). Off loopback,
//! every route but the login needs the token ([`crate::login`]).

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::body::{Body, Bytes};
use axum::extract::{Path, State};
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use futures_util::stream::{self, Stream, StreamExt};
use serde::Deserialize;
use serde_json::json;
use tokio::sync::{mpsc, oneshot};

use gelgrip_controller::grasp_goals::{GoalState, GraspGoals};
use gelgrip_controller::gripper::{GripperError, GripperHandle};

use crate::control::{
    LoopCommand, LoopRequest, MAX_JITTER_US, MAX_UNPLUG_MS, Refusal, ServoFaultName, SimFaults,
    valid_name,
};
use crate::grasps::GoalProgress;
use crate::limits::{Auth, RateLimiter};
use crate::live::{DepthImage, Live};

/// Period of the SSE stream (20 Hz).
pub const EVENTS_PERIOD: Duration = Duration::from_millis(50);

/// Everything the routes need.
#[derive(Debug, Clone)]
pub struct AppState {
    /// What the run loop publishes.
    pub live: Arc<Live>,
    /// The grasp API (`None` when the run has no servos).
    pub gripper: Option<GripperHandle>,
    /// Finger ids, in servo order.
    pub fingers: Vec<String>,
    /// Where task and simulator requests go (`None`: this run takes none).
    pub control: Option<mpsc::Sender<LoopCommand>>,
    /// The configured current limit, mA (the default of a grasp request).
    pub current_limit_ma: f64,
    /// Command authorization.
    pub auth: Auth,
    /// Command rate limit.
    pub limiter: Arc<RateLimiter>,
    /// Grasps started as goals (`POST /api/grasps`).
    pub goals: Arc<GraspGoals>,
}

impl AppState {
    /// A state for `live`, with no token required (loopback) and the default rate limit.
    pub fn new(live: Arc<Live>, gripper: Option<GripperHandle>, fingers: Vec<String>) -> Self {
        Self {
            live,
            gripper,
            fingers,
            control: None,
            current_limit_ma: 1000.0,
            auth: Auth::default(),
            limiter: Arc::new(RateLimiter::default()),
            goals: Arc::new(GraspGoals::new()),
        }
    }

    /// Require `token` on every route but the login (a non-loopback bind).
    pub fn with_token(mut self, token: String) -> Self {
        self.auth = Auth::with_token(token);
        self
    }
}

/// The dashboard's router.
pub fn app(state: AppState) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/api/history", get(api_history))
        .route("/api/grasps", post(crate::grasps::start_goal))
        .route("/api/grasps/{id}", get(crate::grasps::goal))
        .route("/app.js", get(script))
        .route("/axis.js", get(axis_script))
        .route("/style.css", get(style))
        .route("/api/state", get(api_state))
        .route("/api/events", get(events))
        .route("/api/sensors/{id}/stream.mjpg", get(mjpeg))
        .route("/api/sensors/{id}/frame.jpg", get(frame_jpg))
        .route("/api/sensors/{id}/depth.png", get(depth_png))
        .route("/api/sensors/{id}/contact.png", get(contact_png))
        .route("/api/grasp", post(crate::grasps::grasp))
        .route("/api/release", post(release))
        .route("/api/stop", post(stop))
        .route("/api/estop", post(estop))
        .route("/api/task", post(task))
        .route("/api/sim/fault", post(sim_fault))
        .route("/api/sim/scene", post(sim_scene))
        .route("/api/sim/unplug", post(sim_unplug))
        .route("/api/sim/servo", post(sim_servo))
        .fallback(not_found)
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            crate::login::require_token,
        ))
        .merge(crate::login::routes())
        .with_state(state)
}

/// An API error: a status and a message, sent as `{"error": message}`.
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    message: String,
}

impl ApiError {
    pub(crate) fn new(status: StatusCode, message: impl Into<String>) -> Self {
        Self {
            status,
            message: message.into(),
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut r = (self.status, axum::Json(json!({ "error": self.message }))).into_response();
        if self.status == StatusCode::UNAUTHORIZED {
            r.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                axum::http::HeaderValue::from_static("Bearer"),
            );
        }
        r
    }
}

pub(crate) fn error(status: StatusCode, message: impl Into<String>) -> Response {
    ApiError::new(status, message).into_response()
}

async fn not_found() -> Response {
    error(
        StatusCode::NOT_FOUND,
        "no such route; the API is in docs/api.md",
    )
}

async fn index() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/html; charset=utf-8")],
        include_str!("../assets/index.html"),
    )
}

async fn script() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        include_str!("../assets/app.js"),
    )
}

async fn axis_script() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        include_str!("../assets/axis.js"),
    )
}

async fn style() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        include_str!("../assets/style.css"),
    )
}

async fn api_state(State(s): State<AppState>) -> Response {
    axum::Json(s.live.snapshot().as_ref().clone()).into_response()
}

async fn api_history(State(s): State<AppState>) -> Response {
    axum::Json(s.live.history()).into_response()
}

fn json_event(name: &'static str, data: &impl serde::Serialize) -> Event {
    Event::default()
        .event(name)
        .json_data(data)
        .unwrap_or_else(|_| Event::default().event("error").data("unserializable data"))
}

/// `GET /api/events`: a `history` event (the last 30 s of the charted signals), then at
/// 20 Hz the `state`, and a `grasp` event for the newest grasp goal while it runs and once
/// when it ends.
async fn events(State(s): State<AppState>) -> Sse<impl Stream<Item = Result<Event, Infallible>>> {
    let mut interval = tokio::time::interval(EVENTS_PERIOD);
    interval.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let history = json_event("history", &s.live.history());
    let first = stream::iter([Ok::<_, Infallible>(history)]);
    // The goal whose end this stream has sent (so a finished goal is sent once).
    let ended: Option<u64> = None;
    let ticks = stream::unfold(
        (interval, s, ended),
        |(mut interval, s, mut ended)| async move {
            interval.tick().await;
            let snapshot = s.live.snapshot();
            let mut out = vec![Ok(json_event("state", snapshot.as_ref()))];
            if let Some(goal) = s.goals.latest()
                && ended != Some(goal.id)
            {
                if goal.state == GoalState::Done {
                    ended = Some(goal.id);
                }
                out.push(Ok(json_event("grasp", &GoalProgress::of(goal, &snapshot))));
            }
            Some((stream::iter(out), (interval, s, ended)))
        },
    )
    .flatten();
    Sse::new(first.chain(ticks)).keep_alive(KeepAlive::default())
}

fn sensor(s: &AppState, id: &str) -> Result<usize, ApiError> {
    s.live.index_of(id).ok_or_else(|| {
        ApiError::new(
            StatusCode::NOT_FOUND,
            format!("no sensor `{id}`; sensors: {}", s.live.ids().join(", ")),
        )
    })
}

const BOUNDARY: &str = "gelgripframe";

async fn mjpeg(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    let index = match sensor(&s, &id) {
        Ok(i) => i,
        Err(e) => return e.into_response(),
    };
    let Some(mut rx) = s.live.frames(index) else {
        return error(StatusCode::NOT_FOUND, format!("no frames for `{id}`"));
    };
    rx.mark_changed();
    let parts = stream::unfold(rx, |mut rx| async move {
        rx.changed().await.ok()?;
        let jpeg = rx.borrow_and_update().clone();
        let head = format!(
            "--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {}\r\n\r\n",
            jpeg.len()
        );
        let mut part = Vec::with_capacity(head.len() + jpeg.len() + 2);
        part.extend_from_slice(head.as_bytes());
        part.extend_from_slice(&jpeg);
        part.extend_from_slice(b"\r\n");
        Some((Ok::<_, Infallible>(Bytes::from(part)), rx))
    });
    (
        [
            (
                header::CONTENT_TYPE,
                format!("multipart/x-mixed-replace; boundary={BOUNDARY}"),
            ),
            (header::CACHE_CONTROL, "no-cache".to_string()),
        ],
        Body::from_stream(parts),
    )
        .into_response()
}

/// The newest frame, as the hub sent it. The page polls this rather than holding one MJPEG
/// stream per sensor open: browsers allow six HTTP/1.1 connections per host, fewer than the
/// seven (or sixteen) sensors plus the event stream.
async fn frame_jpg(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    let index = match sensor(&s, &id) {
        Ok(i) => i,
        Err(e) => return e.into_response(),
    };
    let jpeg = s
        .live
        .frames(index)
        .map(|rx| rx.borrow().clone())
        .unwrap_or_default();
    if jpeg.is_empty() {
        return error(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("no frame from `{id}` yet"),
        );
    }
    (
        [
            (header::CONTENT_TYPE, "image/jpeg"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        jpeg,
    )
        .into_response()
}

/// 8-bit grey PNG of `pixels` (`width` × `height`).
fn png_grey(width: usize, height: usize, pixels: &[u8]) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, width as u32, height as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()?.write_image_data(pixels)?;
    Ok(out)
}

/// White in a depth image is at least this deep, mm: a free pad's noise stays dark.
const DEPTH_FLOOR_MM: f32 = 0.25;

/// Depth as grey levels: 0 at no indentation, 255 at the deepest point (or
/// [`DEPTH_FLOOR_MM`] when the map is flatter); non-finite depth is black.
fn depth_levels(d: &DepthImage) -> Vec<u8> {
    let max = d
        .depth_mm
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f32, f32::max)
        .max(DEPTH_FLOOR_MM);
    d.depth_mm
        .iter()
        .map(|v| {
            if v.is_finite() {
                (v.max(0.0) / max * 255.0).round() as u8
            } else {
                0
            }
        })
        .collect()
}

fn image(s: &AppState, id: &str, contact: bool) -> Response {
    let index = match sensor(s, id) {
        Ok(i) => i,
        Err(e) => return e.into_response(),
    };
    let Some(d) = s.live.depth(index) else {
        return error(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("no depth map for `{id}` yet (the pipelines publish one per set)"),
        );
    };
    if d.width * d.height != d.depth_mm.len() || d.width == 0 {
        return error(StatusCode::INTERNAL_SERVER_ERROR, "malformed depth map");
    }
    let pixels: Vec<u8> = if contact {
        d.depth_mm
            .iter()
            .map(|v| {
                if v.is_finite() && *v > d.contact_mm {
                    255
                } else {
                    0
                }
            })
            .collect()
    } else {
        depth_levels(&d)
    };
    match png_grey(d.width, d.height, &pixels) {
        Ok(bytes) => ([(header::CONTENT_TYPE, "image/png")], bytes).into_response(),
        Err(e) => error(StatusCode::INTERNAL_SERVER_ERROR, format!("PNG: {e}")),
    }
}

async fn depth_png(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    image(&s, &id, false)
}

async fn contact_png(State(s): State<AppState>, Path(id): Path<String>) -> Response {
    image(&s, &id, true)
}

/// Authorization, then the rate limit (unless `exempt`).
fn authorize(s: &AppState, headers: &HeaderMap, exempt: bool) -> Result<(), ApiError> {
    if !s.auth.allows(headers) {
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            crate::login::NEEDS_TOKEN,
        ));
    }
    if !exempt && !s.limiter.try_take() {
        return Err(ApiError::new(
            StatusCode::TOO_MANY_REQUESTS,
            format!(
                "too many commands: at most {} at once and {} per second (e-stop is never limited)",
                crate::limits::BURST,
                crate::limits::PER_S
            ),
        ));
    }
    Ok(())
}

/// Authorization, then the rate limit (unless `exempt`), then the gripper.
pub(crate) fn admit(
    s: &AppState,
    headers: &HeaderMap,
    exempt: bool,
) -> Result<GripperHandle, ApiError> {
    authorize(s, headers, exempt)?;
    s.gripper.clone().ok_or_else(|| {
        ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "this run has no finger servos: the dashboard only watches it",
        )
    })
}

pub(crate) fn gripper_error(e: &GripperError) -> Response {
    match e {
        GripperError::Stopped => error(StatusCode::SERVICE_UNAVAILABLE, e.to_string()),
        GripperError::Busy { .. } => error(StatusCode::CONFLICT, e.to_string()),
        GripperError::QueueFull { .. } => error(StatusCode::SERVICE_UNAVAILABLE, e.to_string()),
        GripperError::InvalidRequest { .. } => error(StatusCode::BAD_REQUEST, e.to_string()),
    }
}

pub(crate) fn parse<T: serde::de::DeserializeOwned>(body: &Bytes) -> Result<T, ApiError> {
    serde_json::from_slice(body)
        .map_err(|e| ApiError::new(StatusCode::BAD_REQUEST, format!("bad JSON body: {e}")))
}

async fn simple(
    s: AppState,
    headers: HeaderMap,
    exempt: bool,
    what: &str,
    f: fn(&GripperHandle) -> Result<(), GripperError>,
) -> Response {
    let handle = match admit(&s, &headers, exempt) {
        Ok(h) => h,
        Err(e) => return e.into_response(),
    };
    match f(&handle) {
        Ok(()) => axum::Json(json!({ "ok": true, "command": what })).into_response(),
        Err(e) => gripper_error(&e),
    }
}

async fn release(State(s): State<AppState>, headers: HeaderMap) -> Response {
    simple(s, headers, false, "release", GripperHandle::release).await
}

async fn stop(State(s): State<AppState>, headers: HeaderMap) -> Response {
    simple(s, headers, false, "stop", GripperHandle::stop).await
}

async fn estop(State(s): State<AppState>, headers: HeaderMap) -> Response {
    simple(s, headers, true, "estop", GripperHandle::estop).await
}

/// Send `request` to the run loop and turn its answer into a response (`ok` on success).
async fn ask_loop(s: &AppState, request: LoopRequest, ok: serde_json::Value) -> Response {
    let Some(control) = &s.control else {
        return error(
            StatusCode::SERVICE_UNAVAILABLE,
            "this run takes no task or simulator requests from the dashboard",
        );
    };
    let (reply, rx) = oneshot::channel();
    if control.send((request, reply)).await.is_err() {
        return error(StatusCode::SERVICE_UNAVAILABLE, "the run loop has stopped");
    }
    match rx.await {
        Ok(Ok(())) => axum::Json(ok).into_response(),
        Ok(Err(Refusal::Invalid(m))) => error(StatusCode::BAD_REQUEST, m),
        Ok(Err(Refusal::Busy(m))) => error(StatusCode::CONFLICT, m),
        Ok(Err(Refusal::Unavailable(m))) => error(StatusCode::SERVICE_UNAVAILABLE, m),
        Err(_) => error(StatusCode::SERVICE_UNAVAILABLE, "the run loop has stopped"),
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NameBody {
    name: String,
}

/// Parse `{name}` and check it is a bare file stem.
fn name_body(body: &Bytes, what: &str, dir: &str) -> Result<String, ApiError> {
    let b: NameBody = parse(body)?;
    if !valid_name(&b.name) {
        return Err(ApiError::new(
            StatusCode::BAD_REQUEST,
            format!(
                "{what} name {:?}: expected the stem of a file in {dir} (letters, digits, - and _)",
                b.name
            ),
        ));
    }
    Ok(b.name)
}

async fn task(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    if let Err(e) = authorize(&s, &headers, false) {
        return e.into_response();
    }
    let name = match name_body(&body, "task", "configs/tasks") {
        Ok(n) => n,
        Err(e) => return e.into_response(),
    };
    let ok = json!({ "ok": true, "task": name });
    ask_loop(&s, LoopRequest::Task { name }, ok).await
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FaultBody {
    sensor: String,
    #[serde(default)]
    capture_delay_us: u32,
    #[serde(default)]
    delivery_delay_us: u32,
    #[serde(default)]
    drop_rate: f64,
    #[serde(default)]
    corrupt_rate: f64,
    /// Signed, so that a negative jitter is refused with the field's name.
    #[serde(default)]
    capture_jitter_us: i64,
    #[serde(default)]
    clock_drift_ppm: f64,
}

async fn sim_fault(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    if let Err(e) = authorize(&s, &headers, false) {
        return e.into_response();
    }
    let b: FaultBody = match parse(&body) {
        Ok(b) => b,
        Err(e) => return e.into_response(),
    };
    let index = match sensor(&s, &b.sensor) {
        Ok(i) => i,
        Err(e) => return e.into_response(),
    };
    let Ok(capture_jitter_us) = u32::try_from(b.capture_jitter_us) else {
        let m = format!(
            "capture_jitter_us = {}: expected 0 to {MAX_JITTER_US} µs",
            b.capture_jitter_us
        );
        return error(StatusCode::BAD_REQUEST, m);
    };
    let faults = SimFaults {
        capture_delay_us: b.capture_delay_us,
        delivery_delay_us: b.delivery_delay_us,
        drop_rate: b.drop_rate,
        corrupt_rate: b.corrupt_rate,
        capture_jitter_us,
        clock_drift_ppm: b.clock_drift_ppm,
    };
    if let Err(m) = faults.validate() {
        return error(StatusCode::BAD_REQUEST, m);
    }
    let ok = json!({ "ok": true, "sensor": b.sensor, "faults": faults });
    ask_loop(
        &s,
        LoopRequest::SimFault {
            sensor: index,
            faults,
        },
        ok,
    )
    .await
}

async fn sim_scene(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    if let Err(e) = authorize(&s, &headers, false) {
        return e.into_response();
    }
    let name = match name_body(&body, "scene", "configs/scenes") {
        Ok(n) => n,
        Err(e) => return e.into_response(),
    };
    let ok = json!({ "ok": true, "scene": name });
    ask_loop(&s, LoopRequest::SimScene { name }, ok).await
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UnplugBody {
    ms: u32,
}

async fn sim_unplug(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    if let Err(e) = authorize(&s, &headers, false) {
        return e.into_response();
    }
    let b: UnplugBody = match parse(&body) {
        Ok(b) => b,
        Err(e) => return e.into_response(),
    };
    if b.ms == 0 || b.ms > MAX_UNPLUG_MS {
        return error(
            StatusCode::BAD_REQUEST,
            format!("ms = {}: expected 1 to {MAX_UNPLUG_MS}", b.ms),
        );
    }
    let ok = json!({ "ok": true, "unplugged_ms": b.ms });
    ask_loop(&s, LoopRequest::SimUnplug { ms: b.ms }, ok).await
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ServoFaultBody {
    finger: String,
    fault: String,
}

async fn sim_servo(State(s): State<AppState>, headers: HeaderMap, body: Bytes) -> Response {
    if let Err(e) = authorize(&s, &headers, false) {
        return e.into_response();
    }
    let b: ServoFaultBody = match parse(&body) {
        Ok(b) => b,
        Err(e) => return e.into_response(),
    };
    let kind = match b.fault.as_str() {
        "overload" => ServoFaultName::Overload,
        "overheating" => ServoFaultName::Overheating,
        other => {
            return error(
                StatusCode::BAD_REQUEST,
                format!("fault `{other}`: expected overload or overheating"),
            );
        }
    };
    let Some(finger) = s.fingers.iter().position(|f| *f == b.finger) else {
        return error(
            StatusCode::NOT_FOUND,
            format!(
                "no finger `{}`; fingers: {}",
                b.finger,
                s.fingers.join(", ")
            ),
        );
    };
    let ok = json!({ "ok": true, "finger": b.finger, "fault": kind });
    ask_loop(&s, LoopRequest::SimServoFault { finger, kind }, ok).await
}

#[cfg(test)]
mod tests;
