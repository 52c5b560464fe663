//! Helpers shared by the end-to-end tests: run the `gelgrip` binary and read its output.

#![allow(dead_code)] // each test file uses its own subset

use std::process::{Command, Output};

pub mod browser;
pub mod press_hub;
pub mod server;

/// Kills process `pid` (SIGKILL) unless dropped within `timeout`: a child that stops making
/// progress fails its test instead of hanging it.
pub struct Watchdog(std::sync::Arc<std::sync::atomic::AtomicBool>);

impl Watchdog {
    /// Watch `pid` for `timeout`.
    pub fn new(pid: u32, timeout: std::time::Duration) -> Self {
        let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let watch = done.clone();
        std::thread::spawn(move || {
            let deadline = std::time::Instant::now() + timeout;
            while std::time::Instant::now() < deadline {
                std::thread::sleep(std::time::Duration::from_millis(100));
                if watch.load(std::sync::atomic::Ordering::Relaxed) {
                    return;
                }
            }
            let _ = Command::new("kill")
                .args(["-KILL", &pid.to_string()])
                .status();
        });
        Self(done)
    }
}

impl Drop for Watchdog {
    fn drop(&mut self) {
        self.0.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

/// A fresh scratch directory for test `name` (removed first if left over), in the build's
/// own temporary directory (`target/tmp`): one per test however often the tests run, and
/// gone with the build, never piling up in the system's temporary directory.
pub fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("gelgrip-e2e-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// A path as `&str` (the tests' temp paths are UTF-8).
pub fn s(p: &std::path::Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Run `gelgrip` with `args`, logs at warn.
pub fn gelgrip(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("the gelgrip binary runs")
}

/// Stdout of a successful run; fails the test with the exit code, stdout (a report, say
/// which check failed) and stderr otherwise.
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "exit {:?}\nstdout: {}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Stdout of a successful run parsed as exactly one JSON value.
pub fn json(out: &Output) -> serde_json::Value {
    serde_json::from_str(&ok(out)).expect("stdout is exactly one JSON value")
}

/// `gelgrip emulate servos` running in the background on a link in a fresh temp directory.
/// Dropping it kills the process; [`ServoEmulator::stop`] checks the SIGTERM contract.
pub struct ServoEmulator {
    child: std::process::Child,
    /// The link PATH the emulator serves on.
    pub link: std::path::PathBuf,
    /// The one JSON line it printed.
    pub announced: serde_json::Value,
}

impl ServoEmulator {
    /// Start `gelgrip emulate servos --link <tmp>/<name>/dxl --ids IDS --baud BAUD` and wait
    /// for its JSON line.
    pub fn start(name: &str, ids: &str, baud: u32) -> Self {
        Self::launch(name, "servos", &["--ids", ids, "--baud", &baud.to_string()])
    }

    /// Start `gelgrip emulate servos --link <tmp>/<name>/dxl ARGS…` and wait for its JSON
    /// line.
    pub fn start_with(name: &str, args: &[&str]) -> Self {
        Self::launch(name, "servos", args)
    }

    /// Start `gelgrip emulate hub --link <tmp>/<name>/hub --usb USB` and wait for its JSON
    /// line.
    pub fn start_hub(name: &str, usb: &str) -> Self {
        Self::launch(name, "hub", &["--usb", usb])
    }

    fn launch(name: &str, what: &str, args: &[&str]) -> Self {
        use std::io::BufRead;
        let dir = std::env::temp_dir().join(format!("gelgrip-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let link = dir.join(if what == "hub" { "hub" } else { "dxl" });
        let _ = std::fs::remove_file(&link);
        let mut child = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
            .args(["emulate", what, "--link"])
            .arg(&link)
            .args(args)
            .env("RUST_LOG", "warn")
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("the emulator starts");
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("one JSON line");
        let announced = serde_json::from_str(&line).expect("the line is JSON");
        Self {
            child,
            link,
            announced,
        }
    }

    /// The link as a string.
    pub fn path(&self) -> &str {
        self.link.to_str().expect("a UTF-8 temp path")
    }

    /// SIGTERM; the emulator must exit 0 and remove its link.
    pub fn stop(mut self) {
        let status = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .expect("kill runs");
        assert!(status.success());
        let exit = self.child.wait().expect("the emulator exits");
        assert!(exit.success(), "{exit:?}");
        assert!(!self.link.exists(), "the link is removed on SIGTERM");
    }
}

impl Drop for ServoEmulator {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
        // The link's scratch directory (one per emulator and test process).
        if let Some(dir) = self.link.parent() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

/// `gelgrip run --headless --json --clock virtual` with the tests' shared calibration cache
/// (under the build's `target/tmp`) and logs at warn; the caller adds `extra`.
pub fn virtual_run(extra: &[&str]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_gelgrip"));
    cmd.args(["run", "--headless", "--json", "--clock", "virtual"])
        .args(extra)
        .env(
            "GELGRIP_CACHE_DIR",
            std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("gelgrip-cache"),
        )
        .env("RUST_LOG", "warn");
    cmd
}

/// The JSON report of a run that exited with `code` (fails with stderr otherwise).
pub fn report(out: &Output, code: i32) -> serde_json::Value {
    assert_eq!(
        out.status.code(),
        Some(code),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

/// Run `gelgrip` with `args` and the tests' shared calibration cache, logs at warn.
pub fn gelgrip_cached(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args(args)
        .env(
            "GELGRIP_CACHE_DIR",
            std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("gelgrip-cache"),
        )
        .env("RUST_LOG", "warn")
        .output()
        .expect("the gelgrip binary runs")
}
