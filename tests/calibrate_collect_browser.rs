//! The calibration view of `calibrate collect` through the emulated CDC hub (presses on
//! request): over HTTP, every bad request gets a 4xx JSON error and stdin and the page share
//! one decision per press; in a real headless Chromium, a person's session (Redo once, Keep
//! twice) ends with two presses on disk and 2/2 on the page (a screenshot of the view with a
//! press waiting is saved as `calibrate-collect.png` under the build's tmp dir).

mod common;

use std::io::{BufRead, BufReader, Write};
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use common::press_hub::{PressHub, collect_command};
use common::server::{http_with, wait_until};
use common::{s, scratch};

/// Longest wait for one line of the session.
const LINE_TIMEOUT: Duration = Duration::from_secs(30);

/// `calibrate collect` of f1.tip through a [`PressHub`], its view served, its stderr read
/// line by line; killed (with its process group) when dropped.
struct Collect {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<String>,
    log: String,
    /// The view's URL, on 127.0.0.1.
    url: String,
}

impl Collect {
    fn start(hub: &PressHub, out: &Path, presses: &str, bind: &str, env: &[(&str, &str)]) -> Self {
        let mut child = collect_command(&hub.config, out, presses)
            .process_group(0)
            .args(["--http", bind])
            .envs(env.iter().copied())
            .spawn()
            .expect("calibrate collect starts");
        let stdin = child.stdin.take();
        let stderr = child.stderr.take().expect("stderr");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    return;
                }
            }
        });
        let mut c = Self {
            child,
            stdin,
            lines,
            log: String::new(),
            url: String::new(),
        };
        let line = c.until("dashboard: ");
        c.url = line["dashboard: ".len()..]
            .trim()
            .replace("0.0.0.0", "127.0.0.1");
        c
    }

    /// The next stderr line containing `what` (the lines before it are logged).
    fn until(&mut self, what: &str) -> String {
        loop {
            match self.lines.recv_timeout(LINE_TIMEOUT) {
                Ok(line) => {
                    eprintln!("collect: {line}");
                    self.log += &line;
                    self.log.push('\n');
                    if line.contains(what) {
                        return line;
                    }
                }
                Err(e) => panic!("no `{what}` from collect ({e}); its stderr:\n{}", self.log),
            }
        }
    }

    /// Answer the prompt on stdin.
    fn answer(&mut self, line: &str) {
        let stdin = self.stdin.as_mut().expect("stdin open");
        writeln!(stdin, "{line}").expect("collect stdin");
    }

    /// Its exit code and stdout, once it ends (killed after 60 s).
    fn finish(&mut self) -> (Option<i32>, String) {
        let deadline = std::time::Instant::now() + Duration::from_secs(60);
        loop {
            if let Some(status) = self.child.try_wait().expect("collect's status") {
                let mut out = String::new();
                if let Some(mut o) = self.child.stdout.take() {
                    let _ = std::io::Read::read_to_string(&mut o, &mut out);
                }
                return (status.code(), out);
            }
            assert!(
                std::time::Instant::now() < deadline,
                "collect did not end; its stderr:\n{}",
                self.log
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Collect {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", self.child.id())])
            .stderr(Stdio::null())
            .status();
        let _ = self.child.wait();
    }
}

/// Press the 6 mm ball on f1.tip at (`x`, `y`) px, `depth` mm.
fn press(hub: &mut PressHub, x: f64, y: f64, depth: f64) {
    let answer = hub.ask(&format!("f1.tip {x} {y} {depth}"));
    assert!(answer["contact_radius_px"].is_f64(), "{answer}");
}

/// The presses listed in `dir/presses.csv`.
fn listed(dir: &Path) -> Vec<String> {
    let csv = std::fs::read_to_string(dir.join("presses.csv")).expect("presses.csv");
    csv.lines().skip(1).map(str::to_string).collect()
}

const TOKEN: &str = "collect-view-token";

/// Bound off loopback with a token: the token on every route, 409 for a decision with no
/// press waiting or on another press, 400 for a malformed body, all as JSON errors; stdin's
/// answer withdraws the page's question; SIGINT keeps the press kept.
#[test]
fn bad_requests_get_json_errors_and_stdin_and_the_page_share_one_decision() {
    let dir = scratch("collect-view-http");
    let mut hub = PressHub::start(&dir);
    let data = dir.join("data");
    let mut c = Collect::start(
        &hub,
        &data,
        "2",
        "0.0.0.0:0",
        &[("GELGRIP_HTTP_TOKEN", TOKEN)],
    );
    let url = c.url.clone();
    let auth = format!("Authorization: Bearer {TOKEN}");
    let call = |method: &str, path: &str, body: Option<&str>| {
        let (code, body) = http_with(&url, method, path, &[&auth], body);
        let value = serde_json::from_str(&body).unwrap_or(serde_json::Value::Null);
        (code, value, body)
    };
    let error_of = |v: &serde_json::Value| v["error"].as_str().unwrap_or("").to_string();

    // The token: none, or a wrong one.
    let (code, body) = http_with(&url, "GET", "/api/calibrate", &[], None);
    assert_eq!(code, 401, "{body}");
    assert!(body.contains("needs the token"), "{body}");
    let (code, body) = http_with(
        &url,
        "POST",
        "/api/calibrate/keep",
        &["Authorization: Bearer nope"],
        Some(r#"{"attempt": 1}"#),
    );
    assert_eq!(code, 401, "{body}");
    let (code, body) = http_with(&url, "GET", "/", &[], None);
    assert_eq!(code, 401, "the page asks to log in: {body}");
    assert!(body.contains("/login"), "{body}");

    // With it: the status, and no press to decide yet.
    let (code, status, _) = call("GET", "/api/calibrate", None);
    assert_eq!(code, 200);
    assert_eq!(
        (status["wanted"].as_u64(), status["kept"].as_u64()),
        (Some(2), Some(0))
    );
    assert_eq!(status["attempt"], serde_json::Value::Null, "{status}");
    let (code, v, _) = call("POST", "/api/calibrate/keep", Some(r#"{"attempt": 1}"#));
    assert_eq!(code, 409, "{v}");
    assert!(error_of(&v).contains("no press is waiting"), "{v}");
    for bad in ["not json", r#"{"attempt": 1, "extra": 2}"#, ""] {
        let (code, v, raw) = call("POST", "/api/calibrate/redo", Some(bad));
        assert_eq!(code, 400, "{bad}: {raw}");
        assert!(error_of(&v).contains("attempt"), "{bad}: {raw}");
    }
    let (code, v, _) = call("GET", "/api/nothing", None);
    assert_eq!(code, 404, "{v}");
    assert!(!error_of(&v).is_empty());

    // A press waits: another press named is refused; stdin keeps it first.
    c.until("> leave");
    assert_eq!(hub.ask("f1.tip lift")["lifted"], true);
    c.answer("");
    c.until("> press");
    press(&mut hub, 160.0, 120.0, 0.5);
    c.until("> keep");
    let (_, status, _) = call("GET", "/api/calibrate", None);
    let attempt = status["attempt"].as_u64().expect("a press waits");
    assert!(status["label"]["contact_radius_px"].is_f64(), "{status}");
    let (code, _, png) = call("GET", "/api/calibrate/difference.png", None);
    assert_eq!(code, 200);
    assert!(png.starts_with("\u{fffd}PNG"), "a PNG");
    let other = format!(r#"{{"attempt": {}}}"#, attempt + 1);
    let (code, v, _) = call("POST", "/api/calibrate/keep", Some(&other));
    assert_eq!(code, 409, "{v}");
    assert!(
        error_of(&v).ends_with(&format!("press {attempt} is")),
        "{v}"
    );
    c.answer("");
    c.until("kept 1 of 2");
    let this = format!(r#"{{"attempt": {attempt}}}"#);
    let (code, v, _) = call("POST", "/api/calibrate/redo", Some(&this));
    assert_eq!(code, 409, "stdin answered first: {v}");
    let status = wait_until(Duration::from_secs(10), "the count", || {
        let (_, s, _) = call("GET", "/api/calibrate", None);
        (s["kept"] == 1).then_some(s)
    });
    assert_eq!(status["attempt"], serde_json::Value::Null);

    // SIGINT: the press kept stays.
    c.until("> press");
    Command::new("kill")
        .args(["-INT", &c.child.id().to_string()])
        .status()
        .expect("kill");
    let (code, stdout) = c.finish();
    assert_eq!(code, Some(0), "{stdout}\n{}", c.log);
    assert!(stdout.contains("interrupted: 1 of 2"), "{stdout}");
    assert_eq!(listed(&data).len(), 1);
}

/// In headless Chromium: the page shows the difference image and 0/2; Redo once, then
/// Keep twice (the emulator pressed between), each decided on the page alone; two presses
/// on disk, and 2/2 on the page.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "needs chromium: run scripts/test"]
async fn a_collect_decided_on_the_page_keeps_what_the_page_kept() {
    use common::browser::{chromium, start_chromedriver, text, wait_for};
    use fantoccini::Locator;

    let dir = scratch("collect-view-browser");
    let mut hub = PressHub::start(&dir);
    let data = dir.join("data");
    let mut c = Collect::start(&hub, &data, "2", "127.0.0.1:0", &[]);
    let (_driver, webdriver) = start_chromedriver();
    let client = chromium(&webdriver).await;
    client.goto(&c.url).await.expect("the page loads");

    c.until("> leave");
    assert_eq!(hub.ask("f1.tip lift")["lifted"], true);
    c.answer("");
    // The difference image (the sensor's size) and the count.
    wait_for(Duration::from_secs(20), "the difference image", || async {
        let w = client
            .execute(
                "return document.getElementById('difference').naturalWidth",
                vec![],
            )
            .await
            .ok()?;
        (w.as_u64()? == 320).then_some(())
    })
    .await;
    assert_eq!(text(&client, "#count").await, "0/2");

    let click = |id: &'static str| {
        let client = client.clone();
        async move {
            client
                .find(Locator::Id(id))
                .await
                .unwrap_or_else(|e| panic!("the {id} button: {e}"))
                .click()
                .await
                .expect("click");
        }
    };
    // Press n of the session (its attempt number) is labelled and waits on the page.
    let deciding = |n: u64| {
        let client = client.clone();
        async move {
            let phase = wait_for(Duration::from_secs(30), "a press to decide", || async {
                let p = text(&client, "#phase").await;
                let enabled = client
                    .execute("return !document.getElementById('keep').disabled", vec![])
                    .await
                    .ok()?;
                (p.contains(&format!("attempt {n}:")) && enabled.as_bool()?).then_some(p)
            })
            .await;
            let label = text(&client, "#label").await;
            assert!(label.contains("radius"), "{phase}: {label}");
        }
    };

    c.until("> press");
    press(&mut hub, 160.0, 120.0, 0.5);
    deciding(1).await;
    click("redo").await;
    c.until("redo (from the dashboard)");

    c.until("> press");
    press(&mut hub, 110.0, 90.0, 0.6);
    deciding(2).await;
    click("keep").await;
    c.until("keep (from the dashboard)");
    c.until("kept 1 of 2");
    wait_for(Duration::from_secs(10), "1/2", || async {
        (text(&client, "#count").await == "1/2").then_some(())
    })
    .await;

    c.until("> press");
    press(&mut hub, 210.0, 150.0, 0.5);
    deciding(3).await;
    // A screenshot of the view with a press waiting, for a person to look at.
    let png = client.screenshot().await.expect("a screenshot");
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("calibrate-collect.png");
    std::fs::write(&shot, png).expect("screenshot written");
    click("keep").await;
    c.until("kept 2 of 2");
    wait_for(Duration::from_secs(10), "2/2", || async {
        (text(&client, "#count").await == "2/2").then_some(())
    })
    .await;
    let (code, stdout) = c.finish();
    assert_eq!(code, Some(0), "{stdout}\n{}", c.log);
    assert!(stdout.contains("2 presses kept"), "{stdout}");
    let rows = listed(&data);
    assert_eq!(rows.len(), 2, "{rows:?}");
    assert!(rows[0].starts_with("press_000.png") && rows[1].starts_with("press_001.png"));
    assert!(data.join("press_001.png").exists());
    assert_eq!(
        text(&client, "#count").await,
        "2/2",
        "the page's last count"
    );
    client.close().await.expect("session closed");
}

/// The simulator's collect asks nothing: `--http` there is a usage error.
#[test]
fn http_on_the_simulator_is_a_usage_error() {
    let dir = scratch("collect-view-sim");
    let out = common::gelgrip(&[
        "calibrate",
        "collect",
        "--sensor",
        "f1.tip",
        "--presses",
        "1",
        "--out",
        s(&dir.join("data")),
        "--http",
        "127.0.0.1:0",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--http"), "{stderr}");
}
