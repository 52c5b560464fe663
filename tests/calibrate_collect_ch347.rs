//! `calibrate collect` through the CH347 chip emulator (the real CH347 driver and hub
//! protocol, in process), its boards pressed on request through a named pipe
//! (`[hub.ch347.emulator] presses_from`): three presses asked for, collected, labelled
//! where they were pressed, and listed in `presses.csv`.

mod common;

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::Command;

use common::press_hub::collect_command;
use common::{gelgrip, s, scratch};

/// Write one request line to the pipe (opening it waits for the emulator's reader).
fn request(pipe: &Path, line: &str) {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open(pipe)
        .expect("the pipe opens");
    writeln!(f, "{line}").expect("request written");
}

#[test]
fn presses_requested_through_a_pipe_are_collected_over_the_ch347_emulator() {
    let dir = scratch("collect-ch347");
    let pipe = dir.join("presses");
    let made = Command::new("mkfifo").arg(&pipe).status().expect("mkfifo");
    assert!(made.success());
    let layout = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/layouts/three-finger.toml");
    let config = dir.join("ch347.toml");
    std::fs::write(
        &config,
        format!(
            "version = 1\nlayout = {:?}\n[hub]\ntransport = \"ch347\"\ntrigger = \"broadcast\"\n\
             [hub.ch347]\ndevice = \"emulator\"\nspi_clock_index = 1\n\
             cs = [\"cs0\", \"cs1\", \"gpio0\", \"gpio1\", \"gpio2\", \"gpio3\", \"gpio4\"]\n\
             [hub.ch347.emulator]\nseed = 1\npresses_from = {:?}\n\
             [gate]\nmax_age_ms = 200\n[servos]\nbus = \"sim\"\n",
            s(&layout),
            s(&pipe)
        ),
    )
    .expect("config");
    let data = dir.join("data");
    let mut child = collect_command(&config, &data, "3")
        .arg("--headless")
        .spawn()
        .expect("calibrate collect starts");
    // A session that stops making progress fails the test instead of hanging it.
    let watchdog = common::Watchdog::new(child.id(), std::time::Duration::from_secs(90));
    let mut stdin = child.stdin.take().expect("stdin");
    let places = [
        (160.0, 120.0, 0.5),
        (100.0, 80.0, 0.7),
        (220.0, 160.0, 0.35),
    ];
    let (mut next, mut log) = (0, String::new());
    for line in BufReader::new(child.stderr.take().expect("stderr")).lines() {
        let line = line.expect("stderr line");
        log += &line;
        log.push('\n');
        let Some(step) = line.strip_prefix("> ") else {
            continue;
        };
        if step.starts_with("leave") {
            request(&pipe, "f1.tip lift");
        }
        if step.starts_with("press") {
            let (x, y, depth) = places[next];
            next += 1;
            request(&pipe, &format!("f1.tip {x} {y} {depth}"));
        }
        writeln!(stdin,).expect("collect stdin");
    }
    let out = child.wait_with_output().expect("collect exits");
    drop(watchdog);
    assert_eq!(out.status.code(), Some(0), "{log}");
    assert_eq!(next, 3, "{log}");
    let csv = std::fs::read_to_string(data.join("presses.csv")).expect("presses.csv");
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|r| {
            r.split(',')
                .skip(1)
                .map(|v| v.parse().expect("a number"))
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 3, "{csv}");
    for (row, (x, y, _)) in rows.iter().zip(places) {
        let off = (row[0] - x).hypot(row[1] - y);
        assert!(off < 1.5, "centre {row:?} for a press at ({x}, {y}): {log}");
    }
}

/// `presses_from` must be a path.
#[test]
fn a_presses_from_that_is_not_a_path_is_a_config_error() {
    let dir = scratch("collect-ch347-bad");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let layout = root.join("configs/layouts/three-finger.toml");
    let text = std::fs::read_to_string(root.join("tests/configs/ch347-emu.toml"))
        .expect("the fixture")
        .replace("../../configs/layouts/three-finger.toml", s(&layout))
        .replace("seed = 1", "seed = 1\npresses_from = 3");
    let config = dir.join("bad.toml");
    std::fs::write(&config, text).expect("config");
    let out = gelgrip(&["check-config", s(&config)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("presses_from"), "{stderr}");
}
