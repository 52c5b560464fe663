//! `gelgrip emulate hub --presses-on-stdin`: an emulated CDC hub whose boards show ball
//! presses on request, with a config that collects through it (for `calibrate collect`).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

use super::s;

/// `gelgrip emulate hub FLAG` (`--presses-on-stdin` or `--weights-on-stdin`) on `dir/hub`:
/// the child, its stdin, and its stdout's lines after the announcement; killed when dropped.
pub struct StdinHub {
    child: Child,
    stdin: ChildStdin,
    answers: std::io::Lines<BufReader<std::process::ChildStdout>>,
    /// The link it serves on.
    pub link: PathBuf,
}

impl StdinHub {
    /// Start it on `dir/hub` with `flag`, and wait for its announcement.
    pub fn start(dir: &Path, flag: &str) -> Self {
        let link = dir.join("hub");
        let mut child = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
            .args(["emulate", "hub", flag, "--link", s(&link)])
            .env("RUST_LOG", "warn")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("the emulator starts");
        let stdin = child.stdin.take().expect("stdin");
        let mut answers = BufReader::new(child.stdout.take().expect("stdout")).lines();
        let hello = answers.next().expect("announcement").expect("a line");
        assert!(hello.contains("\"pty\""), "{hello}");
        Self {
            child,
            stdin,
            answers,
            link,
        }
    }

    /// Ask the emulator for `line`; its JSON answer.
    pub fn ask(&mut self, line: &str) -> serde_json::Value {
        writeln!(self.stdin, "{line}").expect("emulator stdin");
        let answer = self.answers.next().expect("an answer").expect("a line");
        serde_json::from_str(&answer).expect("the answer is JSON")
    }
}

impl Drop for StdinHub {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `gelgrip emulate hub --presses-on-stdin` on `dir/hub`, with the CDC config on it.
pub struct PressHub {
    hub: StdinHub,
    /// The config that collects through the hub (`transport = "cdc"` on its link).
    pub config: PathBuf,
}

impl PressHub {
    /// Start it on `dir/hub`, with its config in `dir/hw.toml`.
    pub fn start(dir: &Path) -> Self {
        let hub = StdinHub::start(dir, "--presses-on-stdin");
        let layout =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/layouts/three-finger.toml");
        let text = format!(
            "version = 1\nlayout = {:?}\n[hub]\ntransport = \"cdc\"\ntrigger = \"broadcast\"\n\
             [hub.cdc]\nport = {:?}\nusb = \"hs\"\n[gate]\npolicy = \"trigger\"\n\
             [servos]\nbus = \"sim\"\n",
            s(&layout),
            s(&hub.link)
        );
        let config = dir.join("hw.toml");
        std::fs::write(&config, text).expect("config");
        Self { hub, config }
    }

    /// Ask the emulator for `line`; its JSON answer.
    pub fn ask(&mut self, line: &str) -> serde_json::Value {
        self.hub.ask(line)
    }
}

/// `gelgrip calibrate collect` of `presses` presses of a 6 mm ball on f1.tip at 0.0625 mm/px,
/// through `config` into `out`, logs at warn, stdin, stdout and stderr piped (not started).
pub fn collect_command(config: &Path, out: &Path, presses: &str) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_gelgrip"));
    c.args([
        "calibrate",
        "collect",
        "--sensor",
        "f1.tip",
        "--presses",
        presses,
    ])
    .args(["--ball-mm", "6", "--mm-per-px", "0.0625"])
    .args(["--config", s(config), "--out", s(out)])
    .env("RUST_LOG", "warn")
    .stdin(Stdio::piped())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    c
}
