//! Every route, in process (`tower::ServiceExt::oneshot`).

use axum::body::{Body, to_bytes};
use axum::http::{Request, StatusCode};
use tower::ServiceExt;

use gelgrip_controller::grasp::Tuning;
use gelgrip_controller::gripper::GripperService;

use super::*;
use crate::live::{DepthImage, Snapshot};

fn ids() -> Vec<String> {
    ["f1.middle", "f1.tip", "palm"]
        .iter()
        .map(|s| s.to_string())
        .collect()
}

fn fingers() -> Vec<String> {
    ["f1", "f2", "f3"].iter().map(|s| s.to_string()).collect()
}

/// A state with a gripper service (returned, so the test decides whether anything steps it).
fn state() -> (AppState, GripperService) {
    let live = Live::new(ids());
    let (service, handle) =
        GripperService::new(Tuning::default(), vec![100.0; 3], vec![0.0; 3], 800.0);
    (AppState::new(live, Some(handle), fingers()), service)
}

async fn send(app: Router, req: Request<Body>) -> (StatusCode, Vec<u8>, Option<String>) {
    let r = app.oneshot(req).await.expect("response");
    let status = r.status();
    let ctype = r
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .map(str::to_string);
    let body = to_bytes(r.into_body(), 1 << 20).await.expect("body");
    (status, body.to_vec(), ctype)
}

fn get(path: &str) -> Request<Body> {
    Request::get(path).body(Body::empty()).expect("request")
}

fn post(path: &str, body: &str) -> Request<Body> {
    Request::post(path)
        .header(header::CONTENT_TYPE, "application/json")
        .body(Body::from(body.to_string()))
        .expect("request")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[tokio::test]
async fn the_page_and_its_assets_are_served() {
    let (s, _service) = state();
    for (path, kind, needle) in [
        ("/", "text/html", "/app.js"),
        ("/app.js", "text/javascript", "EventSource"),
        ("/style.css", "text/css", ".sensor"),
    ] {
        let (status, body, ctype) = send(app(s.clone()), get(path)).await;
        assert_eq!(status, StatusCode::OK, "{path}");
        assert!(ctype.is_some_and(|c| c.starts_with(kind)), "{path}");
        assert!(text(&body).contains(needle), "{path}");
    }
    let (status, body, _) = send(app(s), get("/nope")).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(text(&body).contains("docs/api.md"));
}

#[tokio::test]
async fn state_is_the_latest_snapshot_with_sensor_ids() {
    let (s, _service) = state();
    s.live.publish(Snapshot {
        t_s: 1.5,
        transport: "sim".into(),
        sensors: ids()
            .into_iter()
            .map(|id| crate::live::SensorView {
                id,
                ok: true,
                ..Default::default()
            })
            .collect(),
        ..Snapshot::default()
    });
    let (status, body, ctype) = send(app(s), get("/api/state")).await;
    assert_eq!(status, StatusCode::OK);
    assert!(ctype.is_some_and(|c| c.starts_with("application/json")));
    let v: serde_json::Value = serde_json::from_slice(&body).expect("json");
    assert_eq!(v["t_s"], 1.5);
    assert_eq!(v["sensors"][1]["id"], "f1.tip");
    assert!(
        v["sync"]["drops"]["out_of_window"].is_u64(),
        "every drop reason present"
    );
}

#[tokio::test]
async fn events_stream_the_state_at_20_hz() {
    let (s, _service) = state();
    let r = app(s).oneshot(get("/api/events")).await.expect("response");
    assert_eq!(r.status(), StatusCode::OK);
    assert!(
        r.headers()[header::CONTENT_TYPE]
            .to_str()
            .is_ok_and(|c| c.starts_with("text/event-stream"))
    );
    let mut body = r.into_body().into_data_stream();
    use futures_util::StreamExt;
    let start = std::time::Instant::now();
    let mut events = 0;
    let mut seen = String::new();
    while events < 5 {
        let chunk = body.next().await.expect("an event").expect("bytes");
        seen.push_str(&text(&chunk));
        events = seen.matches("event: state").count();
    }
    assert!(
        seen.starts_with("event: history"),
        "the history comes first: {}",
        &seen[..seen.len().min(200)]
    );
    let elapsed = start.elapsed().as_secs_f64();
    // Five events at 20 Hz: the first at once, then four periods (0.2 s).
    assert!(elapsed < 0.5, "{elapsed} s for 5 events");
}

#[tokio::test]
async fn mjpeg_forwards_the_hub_jpeg_bytes_and_unknown_sensors_are_404() {
    let (s, _service) = state();
    let jpeg = Bytes::from_static(b"\xff\xd8not really a jpeg\xff\xd9");
    s.live.publish_frame(1, jpeg.clone());
    let r = app(s.clone())
        .oneshot(get("/api/sensors/f1.tip/stream.mjpg"))
        .await
        .expect("response");
    assert_eq!(r.status(), StatusCode::OK);
    assert!(
        r.headers()[header::CONTENT_TYPE]
            .to_str()
            .is_ok_and(|c| c.starts_with("multipart/x-mixed-replace; boundary="))
    );
    let mut body = r.into_body().into_data_stream();
    use futures_util::StreamExt;
    let part = body.next().await.expect("a part").expect("bytes");
    let needle: &[u8] = &jpeg;
    assert!(
        part.windows(needle.len()).any(|w| w == needle),
        "the bytes as the hub sent them"
    );
    assert!(text(&part).contains(&format!("Content-Length: {}", jpeg.len())));
    let (status, body, ctype) = send(app(s.clone()), get("/api/sensors/f1.tip/frame.jpg")).await;
    assert_eq!(status, StatusCode::OK);
    assert_eq!(ctype.as_deref(), Some("image/jpeg"));
    assert_eq!(body, jpeg.to_vec(), "the newest frame, byte for byte");
    let (status, _, _) = send(app(s.clone()), get("/api/sensors/palm/frame.jpg")).await;
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE, "no frame yet");
    let (status, body, _) = send(app(s), get("/api/sensors/f9.tip/stream.mjpg")).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert!(text(&body).contains("f1.middle, f1.tip, palm"));
}

#[tokio::test]
async fn depth_and_contact_are_png_and_wait_for_a_depth_map() {
    let (s, _service) = state();
    let (status, _, _) = send(app(s.clone()), get("/api/sensors/palm/depth.png")).await;
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE);
    s.live.publish_depth(
        2,
        DepthImage {
            width: 4,
            height: 2,
            depth_mm: vec![0.0, 0.1, 0.5, f32::NAN, 0.0, 0.0, 1.0, f32::INFINITY],
            contact_mm: 0.05,
        },
    );
    for kind in ["depth", "contact"] {
        let (status, body, ctype) = send(
            app(s.clone()),
            get(&format!("/api/sensors/palm/{kind}.png")),
        )
        .await;
        assert_eq!(status, StatusCode::OK, "{kind}");
        assert_eq!(ctype.as_deref(), Some("image/png"));
        let decoder = png::Decoder::new(std::io::Cursor::new(body));
        let mut reader = decoder.read_info().expect("a PNG");
        let mut px = vec![0; reader.output_buffer_size().expect("size")];
        reader.next_frame(&mut px).expect("pixels");
        if kind == "contact" {
            assert_eq!(
                &px[..8],
                &[0, 255, 255, 0, 0, 0, 255, 0],
                "non-finite is no contact"
            );
        } else {
            assert_eq!(px[6], 255, "the deepest point is white");
            assert_eq!(px[3], 0, "non-finite depth is black");
        }
    }
    let (status, _, _) = send(app(s), get("/api/sensors/f4.tip/contact.png")).await;
    assert_eq!(status, StatusCode::NOT_FOUND);
}

#[tokio::test]
async fn grasp_reaches_the_service_and_resolves_with_its_outcome() {
    let (s, mut service) = state();
    let handle = s.gripper.clone().expect("gripper");
    // The run loop's side: apply commands; once the grasp is in, stop it.
    let stepper = tokio::spawn(async move {
        loop {
            service.apply_commands(&[0.0; 3]);
            if service
                .controller()
                .is_some_and(|c| c.targets_n()[0] == 2.5)
            {
                let _ = handle.stop();
                service.apply_commands(&[0.0; 3]);
                return service;
            }
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    });
    let (status, body, _) = send(
        app(s),
        post(
            "/api/grasp",
            r#"{"target_force_n": 2.5, "fingers": ["f1", "f3"], "timeout_s": 5}"#,
        ),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{}", text(&body));
    let v: serde_json::Value = serde_json::from_slice(&body).expect("json");
    assert_eq!(v["grasped"], false);
    assert_eq!(v["reason"], "stopped");
    assert_eq!(v["status"].as_array().map(Vec::len), Some(3));
    assert!(v["final_force_n"].is_number());
    stepper.await.expect("stepper");
}

#[tokio::test]
async fn bad_grasp_requests_are_400_with_a_message() {
    let (s, _service) = state();
    for (body, want) in [
        ("{not json", "bad JSON body"),
        (r#"{"speed_deg_s": 10}"#, "missing field `target_force_n`"),
        (
            r#"{"target_force_n": 1, "fingers": ["f7"]}"#,
            "no finger `f7`",
        ),
        (r#"{"target_force_n": -1}"#, "target_force_n"),
        (r#"{"target_force_n": 1, "timeout_s": 1e9}"#, "timeout_s"),
        (r#"{"target_force_n": 1, "bogus": 1}"#, "unknown field"),
        (
            r#"{"target_force_n": "Auto"}"#,
            r#"a force in N or \"auto\""#,
        ),
        (r#"{"target_force_n": true}"#, r#"a force in N or \"auto\""#),
    ] {
        let (status, reply, _) = send(app(s.clone()), post("/api/grasp", body)).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{body}");
        assert!(text(&reply).contains(want), "{body}: {}", text(&reply));
    }
}

#[tokio::test]
async fn release_stop_and_estop_reach_the_service_and_a_stopped_loop_is_503() {
    let (s, service) = state();
    for path in ["/api/release", "/api/stop", "/api/estop"] {
        let (status, body, _) = send(app(s.clone()), post(path, "")).await;
        assert_eq!(status, StatusCode::OK, "{path}");
        assert!(text(&body).contains("\"ok\":true"));
    }
    drop(service);
    let (status, body, _) = send(app(s.clone()), post("/api/stop", "")).await;
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE);
    assert!(text(&body).contains("run loop has stopped"));
    let (status, _, _) = send(app(s), post("/api/grasp", r#"{"target_force_n": 1}"#)).await;
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE);
}

#[tokio::test]
async fn commands_are_rate_limited_except_estop() {
    let (mut s, _service) = state();
    s.limiter = Arc::new(RateLimiter::new(2.0, 0.001));
    let codes = [
        send(app(s.clone()), post("/api/release", "")).await.0,
        send(app(s.clone()), post("/api/release", "")).await.0,
        send(app(s.clone()), post("/api/release", "")).await.0,
    ];
    assert_eq!(
        codes,
        [
            StatusCode::OK,
            StatusCode::OK,
            StatusCode::TOO_MANY_REQUESTS
        ]
    );
    for _ in 0..5 {
        assert_eq!(
            send(app(s.clone()), post("/api/estop", "")).await.0,
            StatusCode::OK
        );
    }
}

#[tokio::test]
async fn off_loopback_commands_need_the_token_even_estop() {
    let (s, _service) = state();
    let s = s.with_token("s3cret".into());
    for path in [
        "/api/release",
        "/api/estop",
        "/api/task",
        "/api/sim/fault",
        "/api/sim/scene",
    ] {
        let (status, body, _) = send(app(s.clone()), post(path, "{}")).await;
        assert_eq!(status, StatusCode::UNAUTHORIZED, "{path}");
        assert!(!text(&body).contains("s3cret"), "the token is never echoed");
    }
    let wrong = Request::post("/api/estop")
        .header(header::AUTHORIZATION, "Bearer guess")
        .body(Body::empty())
        .expect("request");
    assert_eq!(
        send(app(s.clone()), wrong).await.0,
        StatusCode::UNAUTHORIZED
    );
    let right = Request::post("/api/estop")
        .header(header::AUTHORIZATION, "Bearer s3cret")
        .body(Body::empty())
        .expect("request");
    assert_eq!(send(app(s.clone()), right).await.0, StatusCode::OK);
}

#[tokio::test]
async fn off_loopback_every_route_needs_the_token_or_the_login_cookie() {
    let (s, _service) = state();
    let s = s.with_token("s3cret".into());
    for path in [
        "/",
        "/app.js",
        "/api/state",
        "/api/history",
        "/api/events",
        "/api/grasps/1",
    ] {
        let (status, body, _) = send(app(s.clone()), get(path)).await;
        assert_eq!(status, StatusCode::UNAUTHORIZED, "{path}");
        assert!(!text(&body).contains("s3cret"), "the token is never echoed");
    }
    let (_, page, ctype) = send(app(s.clone()), get("/")).await;
    assert!(ctype.is_some_and(|c| c.starts_with("text/html")));
    assert!(
        text(&page).contains("action=\"/login\""),
        "the page offers the login form"
    );
    assert_eq!(send(app(s.clone()), get("/login")).await.0, StatusCode::OK);

    let login = |token: &str| {
        Request::post("/login")
            .header(header::CONTENT_TYPE, "application/x-www-form-urlencoded")
            .body(Body::from(format!("token={token}")))
            .expect("request")
    };
    assert_eq!(
        send(app(s.clone()), login("guess")).await.0,
        StatusCode::UNAUTHORIZED
    );
    let r = app(s.clone())
        .oneshot(login("s3cret"))
        .await
        .expect("response");
    assert_eq!(r.status(), StatusCode::SEE_OTHER);
    let cookie = r.headers()[header::SET_COOKIE]
        .to_str()
        .expect("ASCII")
        .to_string();
    assert!(
        cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"),
        "{cookie}"
    );
    assert!(!cookie.contains("s3cret"), "the cookie is not the token");
    let pair = cookie.split(';').next().expect("name=value").to_string();
    let with_cookie = Request::get("/api/state")
        .header(header::COOKIE, format!("other=1; {pair}"))
        .body(Body::empty())
        .expect("request");
    assert_eq!(send(app(s.clone()), with_cookie).await.0, StatusCode::OK);
    let forged = Request::get("/api/state")
        .header(header::COOKIE, "gelgrip_session=00")
        .body(Body::empty())
        .expect("request");
    assert_eq!(
        send(app(s.clone()), forged).await.0,
        StatusCode::UNAUTHORIZED
    );
    let bearer = Request::get("/api/state")
        .header(header::AUTHORIZATION, "Bearer s3cret")
        .body(Body::empty())
        .expect("request");
    assert_eq!(send(app(s), bearer).await.0, StatusCode::OK);
}

#[tokio::test]
async fn an_auto_grasp_closes_to_the_preload_and_finds_its_own_force() {
    let (s, mut service) = state();
    let (status, body, _) = send(
        app(s.clone()),
        post("/api/grasps", r#"{"target_force_n": "auto"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::ACCEPTED, "{}", text(&body));
    service.apply_commands(&[0.0; 3]);
    let preload_n = gelgrip_controller::grasp::GraspSettings::default().preload_n;
    let targets = service.controller().expect("a grasp").targets_n();
    assert!(targets.iter().all(|t| *t == preload_n), "{targets:?}");
}

#[tokio::test]
async fn grasp_goals_answer_at_once_and_report_by_id() {
    let (s, _service) = state();
    let (status, body, _) = send(
        app(s.clone()),
        post("/api/grasps", r#"{"target_force_n": 2.0}"#),
    )
    .await;
    assert_eq!(status, StatusCode::ACCEPTED, "{}", text(&body));
    let v: serde_json::Value = serde_json::from_slice(&body).expect("JSON");
    assert_eq!(v, json!({"id": 1}));
    let (status, body, _) = send(app(s.clone()), get("/api/grasps/1")).await;
    assert_eq!(status, StatusCode::OK);
    let v: serde_json::Value = serde_json::from_slice(&body).expect("JSON");
    assert_eq!(v, json!({"id": 1, "state": "running", "result": null}));
    for unknown in ["/api/grasps/2", "/api/grasps/0", "/api/grasps/x"] {
        let (status, body, _) = send(app(s.clone()), get(unknown)).await;
        assert_eq!(status, StatusCode::NOT_FOUND, "{unknown}: {}", text(&body));
    }
    let (status, _, _) = send(
        app(s.clone()),
        post("/api/grasps", r#"{"target_force_n": -1}"#),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    let (status, body, _) = send(
        app(s.clone()),
        post("/api/grasps", r#"{"target_force_n": 2.0}"#),
    )
    .await;
    assert_eq!(status, StatusCode::ACCEPTED);
    assert_eq!(text(&body), r#"{"id":2}"#, "a refused request takes no id");
}

/// A stand-in run loop: knows the task `screwdriver` (busy while `busy` is set), the
/// scene `egg`, and accepts faults; records what it carried out.
fn fake_loop(s: &mut AppState, busy: bool) -> std::sync::Arc<std::sync::Mutex<Vec<LoopRequest>>> {
    let (tx, mut rx) = mpsc::channel::<LoopCommand>(4);
    s.control = Some(tx);
    let done = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let log = done.clone();
    tokio::spawn(async move {
        while let Some((request, reply)) = rx.recv().await {
            let answer = match &request {
                LoopRequest::Task { .. } if busy => Err(Refusal::Busy(
                    "task `screwdriver` is driving the gripper".into(),
                )),
                LoopRequest::Task { name } if name != "screwdriver" => {
                    Err(Refusal::Invalid(format!("no task `{name}`")))
                }
                LoopRequest::SimScene { name } if name != "egg" => {
                    Err(Refusal::Invalid(format!("no scene `{name}`")))
                }
                _ => Ok(()),
            };
            if answer.is_ok() {
                log.lock().expect("log").push(request);
            }
            let _ = reply.send(answer);
        }
    });
    done
}

#[tokio::test]
async fn tasks_start_through_the_run_loop_which_may_refuse_them() {
    let (mut s, _service) = state();
    let (status, _, _) = send(
        app(s.clone()),
        post("/api/task", r#"{"name": "screwdriver"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE, "no run loop");
    let done = fake_loop(&mut s, false);
    let (status, body, _) = send(
        app(s.clone()),
        post("/api/task", r#"{"name": "screwdriver"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::OK, "{}", text(&body));
    let (status, body, _) = send(app(s.clone()), post("/api/task", r#"{"name": "juggle"}"#)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(text(&body).contains("no task `juggle`"));
    let (status, _, _) = send(app(s.clone()), post("/api/task", r#"{"nom": 1}"#)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    // A path is never a task name: the page cannot make the loop read arbitrary files.
    for name in ["../../etc/passwd", "tasks/x.toml", "", "a b"] {
        let body = json!({ "name": name }).to_string();
        let (status, reply, _) = send(app(s.clone()), post("/api/task", &body)).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{name:?}");
        assert!(text(&reply).contains("configs/tasks"), "{}", text(&reply));
    }
    assert_eq!(
        *done.lock().expect("log"),
        vec![LoopRequest::Task {
            name: "screwdriver".into()
        }]
    );
    let (mut s, _service) = state();
    fake_loop(&mut s, true);
    let (status, body, _) = send(app(s), post("/api/task", r#"{"name": "screwdriver"}"#)).await;
    assert_eq!(
        status,
        StatusCode::CONFLICT,
        "a running task: {}",
        text(&body)
    );
}

#[tokio::test]
async fn a_grasp_while_a_task_owns_the_gripper_is_a_conflict() {
    let (s, _service) = state();
    s.gripper
        .as_ref()
        .expect("gripper")
        .set_busy(Some("screwdriver"));
    let (status, body, _) = send(
        app(s.clone()),
        post("/api/grasp", r#"{"target_force_n": 2}"#),
    )
    .await;
    assert_eq!(status, StatusCode::CONFLICT);
    assert!(text(&body).contains("screwdriver"), "{}", text(&body));
    let (status, _, _) = send(app(s), post("/api/stop", "")).await;
    assert_eq!(status, StatusCode::OK, "a stop always goes through");
}

#[tokio::test]
async fn sim_faults_are_checked_then_go_to_the_run_loop() {
    let (mut s, _service) = state();
    let body = r#"{"sensor": "f1.tip", "capture_delay_us": 20000}"#;
    let (status, _, _) = send(app(s.clone()), post("/api/sim/fault", body)).await;
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE, "no run loop");
    let done = fake_loop(&mut s, false);
    let (status, reply, _) = send(app(s.clone()), post("/api/sim/fault", body)).await;
    assert_eq!(status, StatusCode::OK, "{}", text(&reply));
    assert!(
        text(&reply).contains("\"capture_delay_us\":20000"),
        "{}",
        text(&reply)
    );
    let (status, _, _) = send(
        app(s.clone()),
        post(
            "/api/sim/fault",
            r#"{"sensor": "f9.tip", "capture_delay_us": 1}"#,
        ),
    )
    .await;
    assert_eq!(status, StatusCode::NOT_FOUND, "unknown sensor");
    for bad in [
        r#"{"sensor": "palm", "drop_rate": 1.5}"#,
        r#"{"sensor": "palm", "capture_delay_us": 5000000}"#,
        r#"{"sensor": "palm", "capture_delay_us": -1}"#,
        r#"{"sensor": "palm", "delay": 1}"#,
        r#"{"capture_delay_us": 1}"#,
        "not json",
    ] {
        let (status, reply, _) = send(app(s.clone()), post("/api/sim/fault", bad)).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{bad}: {}", text(&reply));
        assert!(text(&reply).contains("error"), "{bad}");
    }
    // All zero clears the sensor's faults.
    let (status, _, _) = send(app(s), post("/api/sim/fault", r#"{"sensor": "palm"}"#)).await;
    assert_eq!(status, StatusCode::OK);
    let done = done.lock().expect("log");
    assert_eq!(done.len(), 2);
    assert_eq!(
        done[0],
        LoopRequest::SimFault {
            sensor: 1,
            faults: SimFaults {
                capture_delay_us: 20_000,
                ..SimFaults::default()
            }
        }
    );
    assert!(matches!(done[1], LoopRequest::SimFault { sensor: 2, faults } if !faults.any()));
}

#[tokio::test]
async fn sim_faults_take_capture_jitter_and_clock_drift_within_range() {
    let (mut s, _service) = state();
    let done = fake_loop(&mut s, false);
    let body = r#"{"sensor": "f1.tip", "capture_jitter_us": 300, "clock_drift_ppm": -1000}"#;
    let (status, reply, _) = send(app(s.clone()), post("/api/sim/fault", body)).await;
    assert_eq!(status, StatusCode::OK, "{}", text(&reply));
    let reply = text(&reply);
    assert!(reply.contains("\"capture_jitter_us\":300"), "{reply}");
    assert!(reply.contains("\"clock_drift_ppm\":-1000"), "{reply}");
    assert!(reply.contains("\"capture_delay_us\":0"), "{reply}");
    for (bad, field) in [
        (
            r#"{"sensor": "palm", "clock_drift_ppm": 1001}"#,
            "clock_drift_ppm",
        ),
        (
            r#"{"sensor": "palm", "clock_drift_ppm": -1000.5}"#,
            "clock_drift_ppm",
        ),
        (
            r#"{"sensor": "palm", "capture_jitter_us": 1000001}"#,
            "capture_jitter_us",
        ),
        (
            r#"{"sensor": "palm", "capture_jitter_us": -1}"#,
            "capture_jitter_us",
        ),
        (
            r#"{"sensor": "palm", "clock_drift_ppm": "fast"}"#,
            "bad JSON",
        ),
    ] {
        let (status, reply, _) = send(app(s.clone()), post("/api/sim/fault", bad)).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{bad}: {}", text(&reply));
        assert!(text(&reply).contains(field), "{bad}: {}", text(&reply));
    }
    let done = done.lock().expect("log");
    assert_eq!(
        *done,
        vec![LoopRequest::SimFault {
            sensor: 1,
            faults: SimFaults {
                capture_jitter_us: 300,
                clock_drift_ppm: -1000.0,
                ..SimFaults::default()
            }
        }]
    );
}

#[tokio::test]
async fn sim_scenes_switch_by_name_through_the_run_loop() {
    let (mut s, _service) = state();
    let done = fake_loop(&mut s, false);
    let (status, reply, _) =
        send(app(s.clone()), post("/api/sim/scene", r#"{"name": "egg"}"#)).await;
    assert_eq!(status, StatusCode::OK, "{}", text(&reply));
    let (status, reply, _) = send(
        app(s.clone()),
        post("/api/sim/scene", r#"{"name": "moon"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(text(&reply).contains("no scene `moon`"));
    let (status, _, _) = send(
        app(s.clone()),
        post("/api/sim/scene", r#"{"name": "/tmp/evil"}"#),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    let s = s.with_token("t0ken".into());
    let (status, _, _) = send(app(s), post("/api/sim/scene", r#"{"name": "egg"}"#)).await;
    assert_eq!(
        status,
        StatusCode::UNAUTHORIZED,
        "off loopback it needs the token"
    );
    assert_eq!(
        *done.lock().expect("log"),
        vec![LoopRequest::SimScene { name: "egg".into() }]
    );
}
