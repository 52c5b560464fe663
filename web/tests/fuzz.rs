//! Property tests of the dashboard's HTTP API (issue 45): random methods, paths, headers
//! and bodies, and mutations of each command's valid body (`POST /api/grasp`,
//! `/api/grasps`, `/api/task`, `/api/sim/{fault,scene,unplug,servo}`, release, stop,
//! e-stop, the login form), sent through the app's router in process
//! (`tower::ServiceExt::oneshot`). A run loop stands beside it: it answers the task and
//! simulator requests and steps the grasp API, ending each grasp as soon as it starts. The
//! answer must be a success, a redirect or a 4xx, never a 5xx or a panic; a JSON 4xx says
//! why in `error`.
//!
//! Case counts: `PROPTEST_CASES` (proptest's 256 when unset), capped per test so that
//! `scripts/test`'s 30 000-case step stays short; `GELGRIP_FUZZ_CASES` sets the exact count
//! for a long run outside CI (docs/reliability.md).

use std::time::Duration;

use axum::body::{Body, Bytes, to_bytes};
use axum::http::{Method, Request, StatusCode, header};
use proptest::prelude::*;
use serde_json::{Value, json};
use tokio::sync::mpsc;
use tower::ServiceExt;

use gelgrip_controller::grasp::Tuning;
use gelgrip_controller::gripper::{GripperHandle, GripperService};
use gelgrip_web::control::{LoopCommand, LoopRequest, Refusal};
use gelgrip_web::live::DepthImage;
use gelgrip_web::{AppState, Live, app};

/// Cases per test in CI (`PROPTEST_CASES` above it is capped): a request takes about 0.13 ms.
const CI_CASES: u32 = 10_000;
/// Longest one request may take: a grasp ends within milliseconds of starting here.
const CASE_BUDGET: Duration = Duration::from_secs(10);
/// The token of the cases that run off loopback.
const TOKEN: &str = "s3cret";

#[path = "../../testsupport/fuzz_runner.rs"]
mod fuzz_runner;
use fuzz_runner::check;

const SENSORS: [&str; 3] = ["f1.middle", "f1.tip", "palm"];
const FINGERS: [&str; 3] = ["f1", "f2", "f3"];

/// A fresh app state (a fresh rate limiter: each case's request is its first), with a
/// frame and a depth map for every sensor, and the run loop's ends of its channels.
fn rig(token: bool) -> (AppState, GripperService, mpsc::Receiver<LoopCommand>) {
    let live = Live::new(SENSORS.iter().map(|s| s.to_string()).collect());
    for i in 0..SENSORS.len() {
        live.publish_frame(
            i,
            Bytes::from_static(b"\xff\xd8 not really a JPEG \xff\xd9"),
        );
        live.publish_depth(
            i,
            DepthImage {
                width: 4,
                height: 2,
                depth_mm: vec![0.0, 0.1, f32::NAN, 0.5, -1.0, 2.0, 0.3, f32::INFINITY],
                contact_mm: 0.2,
            },
        );
    }
    let (service, handle) =
        GripperService::new(Tuning::default(), vec![100.0; 3], vec![0.0; 3], 800.0);
    let fingers = FINGERS.iter().map(|s| s.to_string()).collect();
    let mut state = AppState::new(live, Some(handle), fingers);
    let (tx, rx) = mpsc::channel(4);
    state.control = Some(tx);
    if token {
        state = state.with_token(TOKEN.into());
    }
    (state, service, rx)
}

/// The run loop's answer to a task or simulator request.
fn answer(request: &LoopRequest) -> Result<(), Refusal> {
    match request {
        LoopRequest::Task { name } if name != "pick-and-release" => {
            Err(Refusal::Invalid(format!("no task {name}")))
        }
        LoopRequest::SimScene { name } if name != "egg" && name != "none" => {
            Err(Refusal::Invalid(format!("no scene {name}")))
        }
        _ => Ok(()),
    }
}

/// Send `request` while playing the run loop; the status, content type and (unless it
/// is a stream) the body.
async fn serve(token: bool, request: Request<Body>) -> (StatusCode, String, Vec<u8>) {
    let (state, mut service, mut control) = rig(token);
    let handle: GripperHandle = state.gripper.clone().expect("gripper");
    let response = app(state).oneshot(request);
    tokio::pin!(response);
    let response = loop {
        tokio::select! {
            biased;
            r = &mut response => break r.expect("infallible"),
            Some((req, reply)) = control.recv() => {
                let _ = reply.send(answer(&req));
            }
            _ = tokio::time::sleep(Duration::from_millis(1)) => {
                service.apply_commands(&[0.0; 3]);
                if service.controller().is_some() {
                    let _ = handle.stop();
                    service.apply_commands(&[0.0; 3]);
                }
            }
        }
    };
    let status = response.status();
    let ctype = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_string();
    let stream = ctype.starts_with("text/event-stream") || ctype.starts_with("multipart/");
    let body = if stream {
        Vec::new()
    } else {
        let b = to_bytes(response.into_body(), 1 << 22).await;
        b.expect("a whole body").to_vec()
    };
    (status, ctype, body)
}

/// Serve `request` on a runtime that steps virtual time, and check the answer: a
/// success, a redirect or a 4xx (a JSON one with its `error`), in time.
fn answer_is_never_5xx(rt: &tokio::runtime::Runtime, token: bool, request: Request<Body>) {
    let what = format!("{} {}", request.method(), request.uri());
    // A HEAD answer has no body to say why.
    let head = request.method() == Method::HEAD;
    let (status, ctype, body) = rt.block_on(async {
        tokio::time::timeout(CASE_BUDGET, serve(token, request))
            .await
            .unwrap_or_else(|_| panic!("{what}: no answer in {CASE_BUDGET:?}"))
    });
    let text = String::from_utf8_lossy(&body);
    assert!(
        status.is_success() || status.is_redirection() || status.is_client_error(),
        "{what}: {status} {text}"
    );
    if status.is_client_error() && ctype.starts_with("application/json") && !head {
        let v: Value = serde_json::from_slice(&body).expect("a JSON error");
        assert!(
            v["error"].as_str().is_some_and(|e| !e.is_empty()),
            "{what}: {text}"
        );
    }
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
}

/// Each command route and a valid body for it.
fn valid_bodies() -> Vec<(&'static str, Value)> {
    vec![
        (
            "/api/grasp",
            json!({"target_force_n": 2.5, "speed_deg_s": 20, "current_limit_ma": 500,
                   "fingers": ["f1", "f3"], "timeout_s": 5}),
        ),
        (
            "/api/grasps",
            json!({"target_force_n": 1.0, "timeout_s": 2}),
        ),
        ("/api/task", json!({"name": "pick-and-release"})),
        (
            "/api/sim/fault",
            json!({"sensor": "palm", "capture_delay_us": 1000, "delivery_delay_us": 0,
                   "drop_rate": 0.1, "corrupt_rate": 0.0, "capture_jitter_us": 5,
                   "clock_drift_ppm": 10}),
        ),
        ("/api/sim/scene", json!({"name": "egg"})),
        ("/api/sim/unplug", json!({"ms": 100})),
        (
            "/api/sim/servo",
            json!({"finger": "f2", "fault": "overload"}),
        ),
        ("/api/release", json!({})),
        ("/api/stop", json!({})),
        ("/api/estop", json!({})),
    ]
}

fn post(path: &str, body: Vec<u8>) -> Request<Body> {
    Request::post(path)
        .header(header::CONTENT_TYPE, "application/json")
        .body(Body::from(body))
        .expect("request")
}

#[test]
fn every_valid_command_succeeds() {
    let rt = runtime();
    for (path, body) in valid_bodies() {
        let (status, _, reply) = rt.block_on(serve(false, post(path, body.to_string().into())));
        let text = String::from_utf8_lossy(&reply);
        assert!(status.is_success(), "{path}: {status} {text}");
    }
}

#[test]
fn bodies_past_the_limit_or_nested_past_the_parser_are_4xx() {
    let rt = runtime();
    let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
    let big = format!(r#"{{"name": "{}"}}"#, "a".repeat(3 << 20));
    for body in [deep, big] {
        for path in ["/api/task", "/api/grasp"] {
            let (status, _, _) = rt.block_on(serve(false, post(path, body.clone().into())));
            assert!(status.is_client_error(), "{path}: {status}");
        }
    }
}

/// A JSON value a field may be given instead of its own.
fn json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<i64>().prop_map(|v| json!(v)),
        any::<u64>().prop_map(|v| json!(v)),
        any::<f64>().prop_map(|v| json!(v)),
        Just(json!(1e308)),
        Just(json!(-1)),
        Just(json!(0)),
        Just(json!(u64::MAX)),
        "[ -~]{0,12}".prop_map(Value::String),
        Just(json!("../../etc/passwd")),
        Just(json!("f1")),
        Just(json!("palm")),
    ];
    leaf.prop_recursive(3, 12, 4, |inner| {
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..4).prop_map(Value::Array),
            proptest::collection::btree_map("[a-z_]{1,8}", inner, 0..3)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// One change to a valid body.
#[derive(Debug, Clone)]
enum BodyEdit {
    /// The `n`th field set to a value (or a new field added when past the last).
    Set(usize, Value),
    /// The `n`th field removed.
    Remove(usize),
    /// An unknown field added.
    Add(String, Value),
}

fn body_edit() -> impl Strategy<Value = BodyEdit> {
    prop_oneof![
        3 => (0usize..8, json_value()).prop_map(|(n, v)| BodyEdit::Set(n, v)),
        1 => (0usize..8).prop_map(BodyEdit::Remove),
        1 => ("[a-z_]{1,10}", json_value()).prop_map(|(k, v)| BodyEdit::Add(k, v)),
    ]
}

/// `body` with `edits` applied.
fn edit_body(mut body: Value, edits: &[BodyEdit]) -> Value {
    let Some(map) = body.as_object_mut() else {
        return body;
    };
    for e in edits {
        let keys: Vec<String> = map.keys().cloned().collect();
        match e {
            BodyEdit::Set(n, v) => {
                let key = keys.get(*n).cloned().unwrap_or_else(|| format!("x{n}"));
                map.insert(key, v.clone());
            }
            BodyEdit::Remove(n) => {
                if let Some(k) = keys.get(*n) {
                    map.remove(k);
                }
            }
            BodyEdit::Add(k, v) => {
                map.insert(k.clone(), v.clone());
            }
        }
    }
    body
}

/// Byte writes, then a cut, on the body's text.
fn edit_bytes(mut b: Vec<u8>, writes: &[(usize, u8)], cut: Option<usize>) -> Vec<u8> {
    for (at, v) in writes {
        if !b.is_empty() {
            let n = b.len();
            b[at % n] = *v;
        }
    }
    if let Some(c) = cut {
        b.truncate(c % (b.len() + 1));
    }
    b
}

#[test]
fn mutated_command_bodies_are_answered_never_with_a_5xx() {
    let rt = runtime();
    let strategy = (
        0..valid_bodies().len(),
        proptest::collection::vec(body_edit(), 0..4),
        proptest::collection::vec((any::<usize>(), any::<u8>()), 0..3),
        proptest::option::of(any::<usize>()),
    );
    check(CI_CASES, strategy, |(route, edits, writes, cut)| {
        let (path, body) = valid_bodies().swap_remove(route);
        let text = edit_body(body, &edits).to_string().into_bytes();
        answer_is_never_5xx(&rt, false, post(path, edit_bytes(text, &writes, cut)));
    });
}

/// Path segments the routes know, and ones they do not.
fn segment() -> impl Strategy<Value = String> {
    let known = [
        "api",
        "grasp",
        "grasps",
        "sensors",
        "f1.tip",
        "palm",
        "f9",
        "stream.mjpg",
        "frame.jpg",
        "depth.png",
        "contact.png",
        "sim",
        "fault",
        "scene",
        "unplug",
        "servo",
        "task",
        "release",
        "stop",
        "estop",
        "events",
        "state",
        "history",
        "login",
        "app.js",
        "style.css",
        "1",
        "0",
        "18446744073709551616",
        "..",
        "%00",
        "%ff%fe",
        "%2e%2e",
    ];
    prop_oneof![
        4 => proptest::sample::select(known.to_vec()).prop_map(str::to_string),
        1 => "[a-zA-Z0-9._~%-]{0,12}",
    ]
}

/// A request of a random method, path, query, headers and body.
fn random_request() -> impl Strategy<Value = (bool, Method, String, Vec<(String, String)>, Vec<u8>)>
{
    let method = proptest::sample::select(vec![
        Method::GET,
        Method::POST,
        Method::PUT,
        Method::DELETE,
        Method::HEAD,
    ]);
    let path = (
        proptest::collection::vec(segment(), 0..5),
        proptest::option::of("[a-z=&%0-9]{0,16}"),
    )
        .prop_map(|(s, q)| match q {
            Some(q) => format!("/{}?{q}", s.join("/")),
            None => format!("/{}", s.join("/")),
        });
    let header = prop_oneof![
        "[ -~]{0,20}".prop_map(|v| ("authorization".to_string(), format!("Bearer {v}"))),
        Just(("authorization".to_string(), format!("Bearer {TOKEN}"))),
        "[ -~]{0,24}".prop_map(|v| ("cookie".to_string(), format!("gelgrip_session={v}"))),
        "[ -~]{0,24}".prop_map(|v| ("content-type".to_string(), v)),
    ];
    let body = prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..96),
        "token=[ -~]{0,16}".prop_map(String::into_bytes),
        json_value().prop_map(|v| v.to_string().into_bytes()),
    ];
    (
        any::<bool>(),
        method,
        path,
        proptest::collection::vec(header, 0..3),
        body,
    )
}

#[test]
fn random_requests_are_answered_never_with_a_5xx() {
    let rt = runtime();
    check(
        CI_CASES,
        random_request(),
        |(token, method, path, headers, body)| {
            let mut request = Request::builder().method(method).uri(path.as_str());
            for (k, v) in &headers {
                request = request.header(k.as_str(), v.as_str());
            }
            // What the HTTP layer refuses before any route sees it is not ours to test.
            let Ok(request) = request.body(Body::from(body)) else {
                return;
            };
            answer_is_never_5xx(&rt, token, request);
        },
    );
}
