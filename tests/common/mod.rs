//! Helpers shared by the end-to-end tests: run the `gelgrip` binary and read its output.

#![allow(dead_code)] // each test file uses its own subset

use std::process::{Command, Output};

/// Run `gelgrip` with `args`, logs at warn.
pub fn gelgrip(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("the gelgrip binary runs")
}

/// Stdout of a successful run; fails the test with the exit code and stderr otherwise.
pub fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "exit {:?}\nstderr: {}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Stdout of a successful run parsed as exactly one JSON value.
pub fn json(out: &Output) -> serde_json::Value {
    serde_json::from_str(&ok(out)).expect("stdout is exactly one JSON value")
}
