//! One token for everything off loopback: `gelgrip run` bound to 0.0.0.0 with
//! `GELGRIP_HTTP_TOKEN` set, requests sent over 127.0.0.1. Every route (page, assets,
//! state, history, events, streams, frames, images, grasp goals, commands) answers 401
//! without the token and its normal answer with it; the login form sets a session cookie
//! that works in its place; on loopback nothing is asked.

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

mod common;
use common::server::{Start, start_gelgrip_with, wait_until};

const TOKEN: &str = "t0k3n-for-tests";

/// One request; the status, the response head, and the body (only the head for streams,
/// which never end).
fn request(
    url: &str,
    method: &str,
    path: &str,
    headers: &[String],
    body: &str,
) -> (u16, String, String) {
    let host = url.trim_start_matches("http://").trim_end_matches('/');
    let mut stream = TcpStream::connect(host).expect("the dashboard accepts connections");
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .expect("timeout");
    let extra: String = headers.iter().map(|h| format!("{h}\r\n")).collect();
    write!(
        stream,
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n{extra}\
         Content-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .expect("request sent");
    let mut reply = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        let n = stream.read(&mut buf).unwrap_or(0);
        if n == 0 {
            break;
        }
        reply.extend_from_slice(&buf[..n]);
        let text = String::from_utf8_lossy(&reply);
        if let Some((head, _)) = text.split_once("\r\n\r\n") {
            let streaming = head.contains("text/event-stream") || head.contains("multipart/");
            if streaming {
                break;
            }
        }
    }
    let reply = String::from_utf8_lossy(&reply).into_owned();
    let (head, body) = reply.split_once("\r\n\r\n").unwrap_or((&reply, ""));
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no status line in {head:?}"));
    (status, head.to_string(), body.to_string())
}

struct Route {
    method: &'static str,
    path: &'static str,
    body: &'static str,
    /// The normal answer, with the token.
    ok: u16,
}

const fn get(path: &'static str) -> Route {
    Route {
        method: "GET",
        path,
        body: "",
        ok: 200,
    }
}

const fn post(path: &'static str, body: &'static str, ok: u16) -> Route {
    Route {
        method: "POST",
        path,
        body,
        ok,
    }
}

/// Every route, in an order that keeps each answer normal (the scene switches while the
/// fingers are open; the grasp goal exists before it is asked for; the task, the servo
/// fault and the e-stop come last).
const ROUTES: &[Route] = &[
    get("/"),
    get("/app.js"),
    get("/axis.js"),
    get("/style.css"),
    get("/api/state"),
    get("/api/history"),
    get("/api/events"),
    get("/api/sensors/f1.tip/stream.mjpg"),
    get("/api/sensors/f1.tip/frame.jpg"),
    get("/api/sensors/f1.tip/depth.png"),
    get("/api/sensors/f1.tip/contact.png"),
    post("/api/sim/scene", r#"{"name": "tennis-ball"}"#, 200),
    post("/api/sim/fault", r#"{"sensor": "f1.tip"}"#, 200),
    post("/api/sim/unplug", r#"{"ms": 10}"#, 200),
    post(
        "/api/grasp",
        r#"{"target_force_n": 1.5, "timeout_s": 1}"#,
        200,
    ),
    post(
        "/api/grasps",
        r#"{"target_force_n": 1.5, "timeout_s": 1}"#,
        202,
    ),
    get("/api/grasps/1"),
    post("/api/stop", "", 200),
    post("/api/release", "", 200),
    post("/api/task", r#"{"name": "pick-and-release"}"#, 200),
    post(
        "/api/sim/servo",
        r#"{"finger": "f1", "fault": "overload"}"#,
        200,
    ),
    post("/api/estop", "", 200),
];

#[test]
fn off_loopback_every_route_needs_the_token() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("gelgrip-cache");
    let how = Start {
        bind: Some("0.0.0.0:0"),
        env: vec![("GELGRIP_HTTP_TOKEN", TOKEN)],
    };
    let (_run, url) = start_gelgrip_with(&how, &cache, &[]);
    let bearer = vec![format!("Authorization: Bearer {TOKEN}")];
    let json = || vec!["Content-Type: application/json".to_string()];
    // Frames and depth maps exist once sets flow.
    wait_until(Duration::from_secs(30), "depth maps", || {
        let (status, _, _) = request(&url, "GET", "/api/sensors/f1.tip/depth.png", &bearer, "");
        (status == 200).then_some(())
    });

    for r in ROUTES {
        let (status, head, body) = request(&url, r.method, r.path, &json(), r.body);
        assert_eq!(
            status, 401,
            "{} {} without the token: {head}\n{body}",
            r.method, r.path
        );
        assert!(!body.contains(TOKEN), "the token is never echoed");
        let wrong = [json(), vec!["Authorization: Bearer guess".to_string()]].concat();
        let (status, _, _) = request(&url, r.method, r.path, &wrong, r.body);
        assert_eq!(status, 401, "{} {} with a wrong token", r.method, r.path);
        let with = [json(), bearer.clone()].concat();
        let (status, head, body) = request(&url, r.method, r.path, &with, r.body);
        assert_eq!(
            status, r.ok,
            "{} {} with the token: {head}\n{body}",
            r.method, r.path
        );
        // Commands are rate-limited (10 at once, 5 per second).
        if r.method == "POST" {
            std::thread::sleep(Duration::from_millis(250));
        }
    }

    // The page without the token is the login form; logging in sets a session cookie that
    // opens every route, the streams included, as the token does.
    let (status, _, page) = request(&url, "GET", "/", &[], "");
    assert_eq!(status, 401);
    assert!(page.contains("action=\"/login\""), "{page}");
    let (status, _, _) = request(&url, "GET", "/login", &[], "");
    assert_eq!(status, 200, "the login form needs no token");
    let form = vec!["Content-Type: application/x-www-form-urlencoded".to_string()];
    let (status, _, _) = request(&url, "POST", "/login", &form, "token=guess");
    assert_eq!(status, 401);
    let (status, head, _) = request(&url, "POST", "/login", &form, &format!("token={TOKEN}"));
    assert_eq!(status, 303, "{head}");
    let cookie = head
        .lines()
        .find_map(|l| {
            l.strip_prefix("set-cookie: ")
                .or_else(|| l.strip_prefix("Set-Cookie: "))
        })
        .expect("a session cookie")
        .to_string();
    assert!(
        cookie.contains("HttpOnly") && cookie.contains("SameSite=Strict"),
        "{cookie}"
    );
    let pair = cookie.split(';').next().expect("name=value");
    let with_cookie = vec![format!("Cookie: {pair}")];
    for path in [
        "/",
        "/api/state",
        "/api/events",
        "/api/sensors/palm/frame.jpg",
    ] {
        let (status, _, _) = request(&url, "GET", path, &with_cookie, "");
        assert_eq!(status, 200, "{path} with the session cookie");
    }
}

#[test]
fn on_loopback_nothing_is_asked() {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("gelgrip-cache");
    let how = Start {
        bind: None,
        env: vec![("GELGRIP_HTTP_TOKEN", TOKEN)],
    };
    let (_run, url) = start_gelgrip_with(&how, &cache, &[]);
    for path in [
        "/",
        "/api/state",
        "/api/history",
        "/api/events",
        "/api/grasps/1",
    ] {
        let (status, _, _) = request(&url, "GET", path, &[], "");
        let want = if path == "/api/grasps/1" { 404 } else { 200 };
        assert_eq!(status, want, "{path}");
    }
}
