//! `gelgrip emulate hub --presses-on-stdin`: an emulated CDC hub whose boards show ball
//! presses on request, with a config that collects through it (for `calibrate collect`).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

use super::s;

/// `gelgrip emulate hub --presses-on-stdin` on `dir/hub`, with the CDC config on it.
pub struct PressHub {
    child: Child,
    stdin: ChildStdin,
    answers: std::io::Lines<BufReader<std::process::ChildStdout>>,
    /// The config that collects through the hub (`transport = "cdc"` on its link).
    pub config: PathBuf,
}

impl PressHub {
    /// Start it on `dir/hub`, with its config in `dir/hw.toml`.
    pub fn start(dir: &Path) -> Self {
        let link = dir.join("hub");
        let mut child = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
            .args(["emulate", "hub", "--presses-on-stdin", "--link", s(&link)])
            .env("RUST_LOG", "warn")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .expect("the emulator starts");
        let stdin = child.stdin.take().expect("stdin");
        let mut answers = BufReader::new(child.stdout.take().expect("stdout")).lines();
        let hello = answers.next().expect("announcement").expect("a line");
        assert!(hello.contains("\"pty\""), "{hello}");
        let layout =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/layouts/three-finger.toml");
        let text = format!(
            "version = 1\nlayout = {:?}\n[hub]\ntransport = \"cdc\"\ntrigger = \"broadcast\"\n\
             [hub.cdc]\nport = {:?}\nusb = \"hs\"\n[gate]\npolicy = \"trigger\"\n\
             [servos]\nbus = \"sim\"\n",
            s(&layout),
            s(&link)
        );
        let config = dir.join("hw.toml");
        std::fs::write(&config, text).expect("config");
        Self {
            child,
            stdin,
            answers,
            config,
        }
    }

    /// Ask the emulator for `line`; its JSON answer.
    pub fn ask(&mut self, line: &str) -> serde_json::Value {
        writeln!(self.stdin, "{line}").expect("emulator stdin");
        let answer = self.answers.next().expect("an answer").expect("a line");
        serde_json::from_str(&answer).expect("the answer is JSON")
    }
}

impl Drop for PressHub {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
