//! A `gelgrip run` serving its dashboard, for the tests that talk to it over HTTP or
//! through a browser: started in its own process group on a free port, and killed with
//! everything it started when dropped.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Kills the child and everything it started when dropped, even when the test panics: the
/// child leads its own process group, and the whole group gets SIGTERM (gelgrip then ends
/// cleanly; chromedriver's Chromium must not outlive the test and eat the CPU of the next).
pub struct Running(pub Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", "--", &format!("-{}", self.0.id())])
            .status();
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", self.0.id())])
            .status();
        let _ = self.0.wait();
    }
}

pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// Start `gelgrip run` with the dashboard on a free port and `extra` arguments; its URL.
pub fn start_gelgrip(extra: &[&str]) -> (Running, String) {
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("gelgrip-cache");
    start_gelgrip_with(&Start::default(), &cache, extra)
}

/// How to start `gelgrip run` beyond its arguments.
#[derive(Default)]
pub struct Start<'a> {
    /// `--http` (default `127.0.0.1:0`).
    pub bind: Option<&'a str>,
    /// Extra environment.
    pub env: Vec<(&'a str, &'a str)>,
}

/// Start `gelgrip run` as `how` says, with its calibration cache in `cache`; its URL (on
/// 127.0.0.1 when it is bound to every address).
pub fn start_gelgrip_with(
    how: &Start,
    cache: &std::path::Path,
    extra: &[&str],
) -> (Running, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .process_group(0)
        .args([
            "run",
            "--http",
            how.bind.unwrap_or("127.0.0.1:0"),
            "--duration",
            "300",
        ])
        .args(extra)
        .env("GELGRIP_CACHE_DIR", cache)
        .env("RUST_LOG", "warn")
        .envs(how.env.iter().copied())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("gelgrip starts");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        // Its warnings go to the test's output (shown when the test fails).
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            eprintln!("gelgrip: {line}");
            if let Some(url) = line.strip_prefix("dashboard: ") {
                let _ = tx.send(url.trim().replace("0.0.0.0", "127.0.0.1"));
            }
        }
    });
    let url = rx
        .recv_timeout(Duration::from_secs(300))
        .expect("gelgrip prints the dashboard URL (the first run calibrates its sensors)");
    (Running(child), url)
}

/// One HTTP/1.1 request to `url` (`http://host:port/`) + `path`; the status and the body.
pub fn http(url: &str, method: &str, path: &str, body: Option<&str>) -> (u16, String) {
    http_with(url, method, path, &[], body)
}

/// [`http`] with extra `headers` (`Name: value` each).
pub fn http_with(
    url: &str,
    method: &str,
    path: &str,
    headers: &[&str],
    body: Option<&str>,
) -> (u16, String) {
    let host = url
        .trim_start_matches("http://")
        .trim_end_matches('/')
        .to_string();
    let mut stream = TcpStream::connect(&host).expect("the dashboard accepts connections");
    stream
        .set_read_timeout(Some(Duration::from_secs(30)))
        .expect("timeout");
    let body = body.unwrap_or("");
    let extra: String = headers.iter().map(|h| format!("{h}\r\n")).collect();
    write!(
        stream,
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n{extra}\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .expect("request sent");
    let mut reply = Vec::new();
    stream.read_to_end(&mut reply).expect("reply read");
    let reply = String::from_utf8_lossy(&reply).into_owned();
    let status = reply
        .split(' ')
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no status line in {reply:?}"));
    let body = reply
        .split_once("\r\n\r\n")
        .map_or(String::new(), |(_, b)| b.to_string());
    (status, body)
}

/// `POST path` with a JSON `body` (may be empty); the status and the body.
pub fn post(url: &str, path: &str, body: &str) -> (u16, String) {
    http(url, "POST", path, Some(body))
}

/// `GET /api/state`, parsed.
pub fn state(url: &str) -> serde_json::Value {
    let (status, body) = http(url, "GET", "/api/state", None);
    assert_eq!(status, 200, "{body}");
    serde_json::from_str(&body).expect("state JSON")
}

/// Poll `check` every 100 ms until it returns `Some`, or fail with `what` after `timeout`.
pub fn wait_until<T>(timeout: Duration, what: &str, mut check: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(v) = check() {
            return v;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}
