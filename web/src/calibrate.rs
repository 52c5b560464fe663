//! The calibration view of `gelgrip calibrate collect` on a hardware hub: a page that shows
//! the live difference image (the sensor's frame minus its background, with the detected
//! circle drawn on it), the press being decided (its label, or why it was not usable), the
//! count kept so far, and Keep and Redo buttons.
//!
//! The collect session owns a [`CollectView`]: it publishes its [`CollectStatus`] and the
//! difference image into it, and, for each labelled press, asks it for a decision
//! ([`CollectView::ask`]) at the same time as it prompts on stdin. Whichever answers first
//! decides: a `POST /api/calibrate/keep` or `/redo` claims the pending press
//! ([`CollectView::decide`]); a stdin line claims it with [`CollectView::withdraw`], after
//! which a click is refused with 409.
//!
//! Routes ([`app`]): `GET /` (the page), `GET /calibrate.js`, `GET /api/calibrate` (the
//! status, JSON), `GET /api/calibrate/difference.png`, and `POST /api/calibrate/keep` and
//! `POST /api/calibrate/redo` with the body `{"attempt": N}` (the pending press's number,
//! so that a late or repeated click never decides the next press). Errors are JSON
//! `{"error": …}` with a 4xx status. The token scheme and the login are the dashboard's
//! ([`crate::login`]): off loopback every route needs the token; the two commands share the
//! dashboard's rate limit.

use std::sync::{Arc, Mutex, MutexGuard};

use axum::Router;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde::{Deserialize, Serialize};
use serde_json::json;
use tokio::sync::oneshot;

use crate::live::Live;
use crate::routes::{AppState, error};

/// What the session is doing, as the page shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Waiting for Enter on stdin with the sensor untouched, then averaging the background.
    Background,
    /// Waiting for a press to appear and settle.
    Pressing,
    /// A labelled press waits for Keep or Redo.
    Deciding,
    /// Every press wanted was kept.
    Done,
    /// The session ended early (SIGINT, stdin closed, or a failure).
    Ended,
}

/// A detected contact circle, px.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LabelView {
    /// Centre, x.
    pub center_x_px: f64,
    /// Centre, y.
    pub center_y_px: f64,
    /// Contact radius.
    pub contact_radius_px: f64,
    /// Detection score, 0–1.
    pub score: f64,
}

/// The session's state: `GET /api/calibrate`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CollectStatus {
    /// The sensor pressed.
    pub sensor: String,
    /// Presses wanted.
    pub wanted: usize,
    /// Presses kept so far.
    pub kept: usize,
    /// What the session is doing.
    pub phase: Phase,
    /// What the person is asked to do now (the last `> ` prompt, or a note).
    pub message: String,
    /// The number of the press waiting for a decision (`None` when none is).
    pub attempt: Option<u64>,
    /// The label of the last press looked at (`None` when it had none).
    pub label: Option<LabelView>,
    /// Why the last press looked at is not usable (`None` when it is, or none yet).
    pub rejection: Option<String>,
    /// The difference image's number: it grows with each new image (0: none yet).
    pub image: u64,
    /// The ball's diameter, mm.
    pub ball_mm: f64,
    /// Pixel size on the gel, mm.
    pub mm_per_px: f64,
    /// The dataset's directory.
    pub out: String,
}

/// A decision on a labelled press.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Write it to the dataset.
    Keep,
    /// Drop it and press again.
    Redo,
}

impl Decision {
    /// `keep` or `redo`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Keep => "keep",
            Self::Redo => "redo",
        }
    }
}

/// The page's answer on a press: the session acts on it, then calls [`PageAnswer::done`]
/// with its status, which the `POST` answers with (so a Keep's answer counts the press
/// kept, written to disk).
#[derive(Debug)]
pub struct PageAnswer {
    /// Keep or redo.
    pub decision: Decision,
    reply: oneshot::Sender<CollectStatus>,
}

impl PageAnswer {
    /// The session has acted on the answer; `status` is its state now.
    pub fn done(self, status: CollectStatus) {
        let _ = self.reply.send(status);
    }
}

/// Why a decision from the page was not taken.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DecideError {
    /// No press is waiting for a decision.
    NothingPending,
    /// Another press than the one named is waiting.
    OtherPending {
        /// The press named.
        asked: u64,
        /// The press waiting.
        pending: u64,
    },
    /// The session stopped listening.
    Ended,
}

impl std::fmt::Display for DecideError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NothingPending => f.write_str(
                "no press is waiting for a decision (already decided, or none labelled yet)",
            ),
            Self::OtherPending { asked, pending } => write!(
                f,
                "press {asked} is not waiting for a decision; press {pending} is"
            ),
            Self::Ended => f.write_str("the collect session has ended"),
        }
    }
}

impl std::error::Error for DecideError {}

/// An RGB image, 8 bits a channel, row-major.
#[derive(Debug, Clone)]
struct Rgb {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

#[derive(Debug)]
struct Inner {
    status: CollectStatus,
    image: Option<Arc<Rgb>>,
    pending: Option<(u64, oneshot::Sender<PageAnswer>)>,
}

/// What a collect session shares with its page: the status, the difference image, and the
/// press waiting for a decision.
#[derive(Debug)]
pub struct CollectView {
    inner: Mutex<Inner>,
}

impl CollectView {
    /// A view starting at `status`.
    pub fn new(status: CollectStatus) -> Arc<Self> {
        Arc::new(Self {
            inner: Mutex::new(Inner {
                status,
                image: None,
                pending: None,
            }),
        })
    }

    fn lock(&self) -> MutexGuard<'_, Inner> {
        // A panic elsewhere while holding the lock leaves plain data: carry on with it.
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The current status.
    pub fn status(&self) -> CollectStatus {
        self.lock().status.clone()
    }

    /// Change the status.
    pub fn update(&self, f: impl FnOnce(&mut CollectStatus)) {
        f(&mut self.lock().status);
    }

    /// Show a new difference image, `width` × `height` RGB (a buffer of another length
    /// is ignored).
    pub fn set_image(&self, width: usize, height: usize, data: Vec<u8>) {
        if data.len() != width * height * 3 {
            return;
        }
        let mut g = self.lock();
        g.image = Some(Arc::new(Rgb {
            width,
            height,
            data,
        }));
        g.status.image += 1;
    }

    /// Ask the page for a decision on press `attempt` (replacing any earlier question);
    /// the answer comes on the receiver when the page answers first.
    pub fn ask(&self, attempt: u64) -> oneshot::Receiver<PageAnswer> {
        let (tx, rx) = oneshot::channel();
        let mut g = self.lock();
        g.pending = Some((attempt, tx));
        g.status.attempt = Some(attempt);
        g.status.phase = Phase::Deciding;
        rx
    }

    /// Withdraw the question on press `attempt` (stdin answered): true when it was still
    /// open, false when the page had already claimed it (its answer is then on the
    /// receiver [`CollectView::ask`] returned).
    pub fn withdraw(&self, attempt: u64) -> bool {
        let mut g = self.lock();
        let open = g.pending.as_ref().is_some_and(|(a, _)| *a == attempt);
        if open {
            g.pending = None;
            g.status.attempt = None;
        }
        open
    }

    /// The page's answer on press `attempt`: claims the question, so stdin's answer is then
    /// ignored; the receiver gets the session's status once it has acted on the answer.
    pub fn decide(
        &self,
        attempt: u64,
        decision: Decision,
    ) -> Result<oneshot::Receiver<CollectStatus>, DecideError> {
        let mut g = self.lock();
        let pending = match &g.pending {
            None => return Err(DecideError::NothingPending),
            Some((a, _)) if *a != attempt => {
                return Err(DecideError::OtherPending {
                    asked: attempt,
                    pending: *a,
                });
            }
            Some(_) => g.pending.take(),
        };
        g.status.attempt = None;
        let Some((_, tx)) = pending else {
            return Err(DecideError::NothingPending);
        };
        let (reply, done) = oneshot::channel();
        tx.send(PageAnswer { decision, reply })
            .map_err(|_| DecideError::Ended)?;
        Ok(done)
    }

    /// End the session's questions: the page's commands are refused from now on.
    pub fn end(&self, phase: Phase, message: String) {
        let mut g = self.lock();
        g.pending = None;
        g.status.attempt = None;
        g.status.phase = phase;
        g.status.message = message;
    }

    fn image(&self) -> Option<Arc<Rgb>> {
        self.lock().image.clone()
    }
}

#[derive(Debug, Clone)]
struct ViewState {
    app: AppState,
    view: Arc<CollectView>,
}

/// The calibration view's router for `view`; with `token` (a non-loopback bind) every route
/// but the login needs it, as on the dashboard.
pub fn app(view: Arc<CollectView>, token: Option<String>) -> Router {
    let mut state = AppState::new(Live::new(Vec::new()), None, Vec::new());
    if let Some(t) = token {
        state = state.with_token(t);
    }
    Router::new()
        .route(
            "/",
            get(|| async {
                asset(
                    "text/html; charset=utf-8",
                    include_str!("../assets/calibrate.html"),
                )
            }),
        )
        .route(
            "/calibrate.js",
            get(|| async {
                asset(
                    "text/javascript; charset=utf-8",
                    include_str!("../assets/calibrate.js"),
                )
            }),
        )
        .route("/api/calibrate", get(status))
        .route("/api/calibrate/difference.png", get(difference_png))
        .route("/api/calibrate/keep", post(keep))
        .route("/api/calibrate/redo", post(redo))
        .fallback(not_found)
        .with_state(ViewState {
            app: state.clone(),
            view,
        })
        .layer(axum::middleware::from_fn_with_state(
            state.clone(),
            crate::login::require_token,
        ))
        .merge(crate::login::routes())
        .with_state(state)
}

async fn not_found() -> Response {
    error(
        StatusCode::NOT_FOUND,
        "no such route; the calibration view's routes are in docs/calibration.md",
    )
}

/// A page asset, as text of `content_type`.
fn asset(content_type: &'static str, body: &'static str) -> Response {
    ([(header::CONTENT_TYPE, content_type)], body).into_response()
}

async fn status(State(s): State<ViewState>) -> Response {
    (
        [(header::CACHE_CONTROL, "no-store")],
        axum::Json(s.view.status()),
    )
        .into_response()
}

async fn difference_png(State(s): State<ViewState>) -> Response {
    let Some(img) = s.view.image() else {
        return error(
            StatusCode::NOT_FOUND,
            "no difference image yet: the background is not taken",
        );
    };
    match png_rgb(&img) {
        Ok(bytes) => (
            [
                (header::CONTENT_TYPE, "image/png"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            bytes,
        )
            .into_response(),
        Err(e) => error(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("encoding the difference image: {e}"),
        ),
    }
}

fn png_rgb(img: &Rgb) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, img.width as u32, img.height as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    let mut w = enc.write_header()?;
    w.write_image_data(&img.data)?;
    w.finish()?;
    Ok(out)
}

/// Longest a decision's `POST` waits for the session to act on it.
const ACT_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(10);

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DecisionBody {
    attempt: u64,
}

async fn keep(State(s): State<ViewState>, body: Bytes) -> Response {
    decide(&s, &body, Decision::Keep).await
}

async fn redo(State(s): State<ViewState>, body: Bytes) -> Response {
    decide(&s, &body, Decision::Redo).await
}

/// A decision from the page: rate-limited like the dashboard's commands, then the body,
/// then the session.
async fn decide(s: &ViewState, body: &[u8], decision: Decision) -> Response {
    if !s.app.limiter.try_take() {
        return error(
            StatusCode::TOO_MANY_REQUESTS,
            format!(
                "too many commands: at most {} at once and {} per second",
                crate::limits::BURST,
                crate::limits::PER_S
            ),
        );
    }
    let attempt = match serde_json::from_slice::<DecisionBody>(body) {
        Ok(b) => b.attempt,
        Err(e) => {
            return error(
                StatusCode::BAD_REQUEST,
                format!(
                    "expected a JSON body {{\"attempt\": N}} naming the press waiting (`attempt` in GET /api/calibrate): {e}"
                ),
            );
        }
    };
    let done = match s.view.decide(attempt, decision) {
        Ok(done) => done,
        Err(e) => return error(StatusCode::CONFLICT, e.to_string()),
    };
    // The session acts at once (a keep writes one PNG); the status after it, or as it is
    // should the session stop first.
    let status = match tokio::time::timeout(ACT_TIMEOUT, done).await {
        Ok(Ok(status)) => status,
        _ => s.view.status(),
    };
    axum::Json(json!({
        "ok": true,
        "decision": decision.as_str(),
        "attempt": attempt,
        "status": status,
    }))
    .into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status() -> CollectStatus {
        CollectStatus {
            sensor: "f1.tip".into(),
            wanted: 2,
            kept: 0,
            phase: Phase::Pressing,
            message: String::new(),
            attempt: None,
            label: None,
            rejection: None,
            image: 0,
            ball_mm: 6.0,
            mm_per_px: 0.0625,
            out: "data".into(),
        }
    }

    #[test]
    fn one_answer_per_press_whichever_comes_first() {
        let view = CollectView::new(status());
        assert_eq!(
            view.decide(1, Decision::Keep).err(),
            Some(DecideError::NothingPending)
        );
        // The page answers first: stdin's later answer finds the question claimed.
        let mut rx = view.ask(1);
        assert_eq!(view.status().attempt, Some(1));
        assert_eq!(
            view.decide(2, Decision::Keep).err(),
            Some(DecideError::OtherPending {
                asked: 2,
                pending: 1
            })
        );
        let mut done = view.decide(1, Decision::Redo).expect("taken");
        let answer = rx.try_recv().expect("the page's answer");
        assert_eq!(answer.decision, Decision::Redo);
        answer.done(view.status());
        assert_eq!(done.try_recv().map(|s| s.wanted), Ok(2));
        assert!(!view.withdraw(1));
        assert_eq!(
            view.decide(1, Decision::Keep).err(),
            Some(DecideError::NothingPending)
        );
        // Stdin answers first: the page's later click is refused.
        let _rx = view.ask(2);
        assert!(view.withdraw(2));
        assert_eq!(view.status().attempt, None);
        assert_eq!(
            view.decide(2, Decision::Keep).err(),
            Some(DecideError::NothingPending)
        );
        // A session that stopped listening.
        drop(view.ask(3));
        assert_eq!(
            view.decide(3, Decision::Keep).err(),
            Some(DecideError::Ended)
        );
    }

    async fn send(
        app: &Router,
        method: &str,
        path: &str,
        auth: Option<&str>,
        body: &str,
    ) -> (StatusCode, serde_json::Value) {
        use tower::ServiceExt;
        let mut req = axum::http::Request::builder().method(method).uri(path);
        if let Some(token) = auth {
            req = req.header(header::AUTHORIZATION, format!("Bearer {token}"));
        }
        let req = req
            .body(axum::body::Body::from(body.to_string()))
            .expect("request");
        let r = app.clone().oneshot(req).await.expect("response");
        let status = r.status();
        let bytes = axum::body::to_bytes(r.into_body(), 1 << 20)
            .await
            .expect("body");
        let value = serde_json::from_slice(&bytes).unwrap_or(serde_json::Value::Null);
        (status, value)
    }

    #[tokio::test]
    async fn bad_requests_get_json_errors() {
        let view = CollectView::new(status());
        let app = app(view.clone(), Some("sesame".into()));
        let ok = Some("sesame");
        // The token, on every route.
        for (method, path) in [
            ("GET", "/api/calibrate"),
            ("GET", "/api/calibrate/difference.png"),
            ("POST", "/api/calibrate/keep"),
        ] {
            let (code, body) = send(&app, method, path, Some("wrong"), r#"{"attempt": 1}"#).await;
            assert_eq!(code, StatusCode::UNAUTHORIZED, "{method} {path}");
            assert!(
                body["error"].as_str().is_some_and(|e| e.contains("token")),
                "{body}"
            );
        }
        let (code, body) = send(&app, "GET", "/api/calibrate", ok, "").await;
        assert_eq!(code, StatusCode::OK);
        assert_eq!(body["wanted"], 2);
        assert_eq!(body["attempt"], serde_json::Value::Null);
        let (code, _) = send(&app, "GET", "/api/calibrate/difference.png", ok, "").await;
        assert_eq!(code, StatusCode::NOT_FOUND, "no image yet");
        // Nothing to decide.
        let (code, body) = send(&app, "POST", "/api/calibrate/keep", ok, r#"{"attempt": 1}"#).await;
        assert_eq!(code, StatusCode::CONFLICT, "{body}");
        assert!(
            body["error"]
                .as_str()
                .is_some_and(|e| e.contains("no press is waiting"))
        );
        // Malformed bodies.
        let rx = view.ask(1);
        for bad in [
            "",
            "{",
            r#"{"attempt": "one"}"#,
            r#"{"attempt": -1}"#,
            r#"{"press": 1}"#,
        ] {
            let (code, body) = send(&app, "POST", "/api/calibrate/redo", ok, bad).await;
            assert_eq!(code, StatusCode::BAD_REQUEST, "{bad}: {body}");
            assert!(
                body["error"]
                    .as_str()
                    .is_some_and(|e| e.contains("attempt")),
                "{body}"
            );
        }
        // Another press named, then the right one.
        let (code, body) = send(&app, "POST", "/api/calibrate/keep", ok, r#"{"attempt": 7}"#).await;
        assert_eq!(code, StatusCode::CONFLICT, "{body}");
        let session = tokio::spawn(async move {
            let answer = rx.await.expect("the page's answer");
            assert_eq!(answer.decision, Decision::Keep);
            let mut now = status();
            now.kept = 1;
            answer.done(now);
        });
        let (code, body) = send(&app, "POST", "/api/calibrate/keep", ok, r#"{"attempt": 1}"#).await;
        assert_eq!(code, StatusCode::OK, "{body}");
        assert_eq!(body["decision"], "keep");
        assert_eq!(body["status"]["kept"], 1, "answered once acted on");
        session.await.expect("the session's side");
        let (code, _) = send(&app, "GET", "/no/such/route", ok, "").await;
        assert_eq!(code, StatusCode::NOT_FOUND);
    }

    #[test]
    fn images_are_counted_and_encoded() {
        let view = CollectView::new(status());
        view.set_image(2, 1, vec![0; 5]);
        assert_eq!(
            view.status().image,
            0,
            "a buffer of the wrong size is ignored"
        );
        view.set_image(2, 1, vec![255, 0, 0, 0, 0, 255]);
        assert_eq!(view.status().image, 1);
        let png = png_rgb(&view.image().expect("an image")).expect("encoded");
        assert_eq!(&png[1..4], b"PNG");
    }
}
