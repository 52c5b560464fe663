//! A `gelgrip run` child serving its dashboard, for the benches that drive one over HTTP
//! (`bench dashboard`, whose HTTP clients must not share the server's CPU): started with `--http 127.0.0.1:0`, its address read
//! from the `dashboard: URL` line on its stderr (panics there are echoed), stopped with
//! SIGTERM.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use anyhow::Context;

/// The running child.
#[derive(Debug)]
pub struct DashboardChild {
    /// The process.
    pub child: Child,
    /// `host:port` of its dashboard.
    pub addr: String,
}

impl DashboardChild {
    /// Start `gelgrip run --http 127.0.0.1:0` plus `extra`, stdout piped when
    /// `capture_stdout`, and wait (up to 5 minutes: a first run calibrates) for its address.
    pub async fn start(extra: &[&str], capture_stdout: bool) -> anyhow::Result<Self> {
        let exe = std::env::current_exe().context("locating the gelgrip binary")?;
        let mut child = Command::new(exe)
            .args(["run", "--http", "127.0.0.1:0"])
            .args(extra)
            .env("RUST_LOG", "warn")
            .stdout(if capture_stdout {
                Stdio::piped()
            } else {
                Stdio::null()
            })
            .stderr(Stdio::piped())
            .spawn()
            .context("starting gelgrip run")?;
        let stderr = child.stderr.take().context("stderr")?;
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if let Some(url) = line.strip_prefix("dashboard: ") {
                    let _ = tx.send(url.trim().to_string());
                }
                if line.contains("panicked") {
                    eprintln!("gelgrip run: {line}");
                }
            }
        });
        let url =
            tokio::task::spawn_blocking(move || rx.recv_timeout(Duration::from_secs(300))).await?;
        let url = match url {
            Ok(url) => url,
            Err(_) => {
                let mut child = Self {
                    child,
                    addr: String::new(),
                };
                child.terminate();
                anyhow::bail!("gelgrip run did not print its dashboard URL");
            }
        };
        let addr = url
            .trim_start_matches("http://")
            .trim_end_matches('/')
            .to_string();
        Ok(Self { child, addr })
    }

    /// The process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Send SIGTERM (the run stops cleanly and prints its report) without waiting.
    pub fn terminate(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
    }
}

impl Drop for DashboardChild {
    /// A bench that fails midway still stops its child.
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            self.terminate();
            let _ = self.child.wait();
        }
    }
}
