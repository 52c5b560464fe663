//! Recording and replay end to end: `run --record`, `record info`, `replay` (the gate's
//! decisions and every fused reading reproduced bit for bit; another calibration shows its
//! difference), the `replay` transport, and a recorder killed mid-run.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn scratch(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("recording-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn repo(path: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(path)
        .display()
        .to_string()
}

fn info(dir: &Path) -> serde_json::Value {
    common::json(&common::gelgrip(&[
        "record",
        "info",
        dir.to_str().expect("path"),
        "--json",
    ]))
}

#[test]
fn a_recorded_grasp_replays_bit_for_bit_and_another_calibration_shows() {
    let dir = scratch("grasp");
    let out = common::virtual_run(&[
        "--scene",
        &repo("configs/scenes/tennis-ball.toml"),
        "--task",
        "gentle-grasp",
        "--record",
        dir.to_str().expect("path"),
    ])
    .output()
    .expect("runs");
    let run = common::report(&out, 0);
    let sets = run["sets"].as_u64().expect("sets");
    assert!(sets > 100, "{run}");
    let rec = &run["recording"];
    assert_eq!(rec["dropped_backpressure"], 0, "{rec}");
    assert_eq!(rec["error"], serde_json::Value::Null, "{rec}");

    let i = info(&dir);
    assert_eq!(
        i["frames"], run["frames_received"],
        "every frame delivered: {i}"
    );
    assert_eq!(i["crc_errors"], 0);
    assert_eq!(i["truncated_tail_bytes"], 0);
    assert_eq!(i["clean_end"], true);
    assert_eq!(i["segments"], 1);
    assert!(i["duration_s"].as_f64().unwrap_or(0.0) > 3.0, "{i}");

    let replay = common::json(&common::gelgrip_cached(&[
        "replay",
        dir.to_str().expect("path"),
        "--json",
    ]));
    assert_eq!(replay["sets"].as_u64(), Some(sets), "{replay}");
    assert_eq!(
        replay["decisions_recorded"].as_u64(),
        Some(sets),
        "{replay}"
    );
    assert_eq!(replay["decision_mismatches"], 0, "{replay}");
    assert_eq!(replay["fused_compared"].as_u64(), Some(sets), "{replay}");
    assert_eq!(replay["fused_mismatches"], 0, "bit for bit: {replay}");
    // The controller, on the recorded commands and servo states and the replayed sets,
    // decides exactly as it did.
    assert_eq!(
        replay["controller_steps_compared"].as_u64(),
        Some(sets),
        "{replay}"
    );
    assert_eq!(replay["controller_mismatches"], 0, "bit for bit: {replay}");

    // Another force calibration: other readings, other decisions.
    let other = common::json(&common::gelgrip_cached(&[
        "replay",
        dir.to_str().expect("path"),
        "--config",
        &repo("tests/configs/other-force-calibration.toml"),
        "--json",
    ]));
    assert!(
        other["fused_mismatches"].as_u64() > Some(sets / 2),
        "{other}"
    );
    assert!(other["controller_mismatches"].as_u64() > Some(0), "{other}");
    assert_eq!(
        other["decision_mismatches"], 0,
        "the gate does not depend on it"
    );

    let compare = common::json(&common::gelgrip_cached(&[
        "replay",
        dir.to_str().expect("path"),
        "--compare",
        &repo("configs/gelgripper-sim.toml"),
        &repo("tests/configs/other-force-calibration.toml"),
        "--json",
    ]));
    let d = &compare["compare"];
    assert_eq!(d["readings"].as_u64(), Some(sets * 7), "{compare}");
    // Only the force calibration differs: the same depth and area, another force.
    assert_eq!(d["depth_max_abs_mm"], 0.0, "{d}");
    assert_eq!(d["area_max_abs_mm2"], 0.0, "{d}");
    assert!(d["force_mae_n"].as_f64().unwrap_or(0.0) > 0.01, "{d}");

    // Export: frames as PNG with an index, signals as CSV, depth maps as .npy.
    let exported = dir.with_extension("export");
    let _ = std::fs::remove_dir_all(&exported);
    let out = common::gelgrip_cached(&[
        "record",
        "export",
        dir.to_str().expect("path"),
        "--frames",
        exported.join("frames").to_str().expect("path"),
        "--csv",
        exported.join("signals.csv").to_str().expect("path"),
        "--npy",
        exported.join("depth").to_str().expect("path"),
    ]);
    common::ok(&out);
    let lines = |p: PathBuf| {
        std::fs::read_to_string(&p)
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
            .lines()
            .count() as u64
    };
    let frames = run["frames_received"].as_u64().expect("frames");
    assert_eq!(lines(exported.join("frames/frames.csv")), frames + 1);
    assert_eq!(lines(exported.join("signals.csv")), sets + 1);
    let files = |d: &str| std::fs::read_dir(exported.join(d)).map_or(0, |r| r.count() as u64);
    assert_eq!(files("frames/palm"), sets, "one PNG per set and sensor");
    assert_eq!(
        files("depth/palm"),
        sets,
        "one depth map per emitted set and sensor"
    );
    let png = std::fs::read(exported.join("frames/palm/00000010.png")).expect("a PNG");
    assert!(png.starts_with(b"\x89PNG"), "a PNG file");
    let npy = std::fs::read(exported.join("depth/palm/00000010.npy")).expect("an npy");
    assert!(npy.starts_with(b"\x93NUMPY"), "an npy file");
    let _ = std::fs::remove_dir_all(&exported);

    // The replay transport: the same sets through `run`.
    let config = dir.with_extension("toml");
    std::fs::write(
        &config,
        format!(
            "version = 1\nlayout = \"{}\"\n[hub]\ntransport = \"replay\"\n[hub.replay]\ndir = \"{}\"\nspeed = \"max\"\n",
            repo("configs/layouts/three-finger.toml"),
            dir.display()
        ),
    )
    .expect("config");
    let out = common::virtual_run(&["--config", config.to_str().expect("path")])
        .output()
        .expect("runs");
    let replayed = common::report(&out, 0);
    assert_eq!(replayed["transport"], "replay");
    assert_eq!(replayed["end_reason"], "done", "the recording's end");
    assert_eq!(replayed["sets"].as_u64(), Some(sets), "{replayed}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_recorder_killed_mid_run_leaves_every_whole_record_readable() {
    let dir = scratch("killed");
    let mut child = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args([
            "run",
            "--headless",
            "--clock",
            "real",
            "--duration",
            "60",
            "--record",
            dir.to_str().expect("path"),
        ])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("starts");
    let segment = dir.join("segment-000000.ggrec");
    let t0 = Instant::now();
    while std::fs::metadata(&segment).map_or(0, |m| m.len()) < 3_000_000 {
        assert!(
            t0.elapsed() < Duration::from_secs(30),
            "the recording grows"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().expect("SIGKILL");
    let _ = child.wait();

    let i = info(&dir);
    assert_eq!(i["crc_errors"], 0, "every whole record checks: {i}");
    assert_eq!(i["clean_end"], false, "{i}");
    assert!(i["frames"].as_u64().unwrap_or(0) >= 100, "{i}");
    let torn_at_kill = i["truncated_tail_bytes"].as_u64().expect("reported");

    // A torn write (as a power cut leaves): cut the last whole record 5 bytes short.
    let len = std::fs::metadata(&segment).expect("segment").len();
    let file = std::fs::OpenOptions::new()
        .write(true)
        .open(&segment)
        .expect("open");
    file.set_len(len - torn_at_kill - 5).expect("cut");
    let cut = info(&dir);
    assert_eq!(cut["crc_errors"], 0, "{cut}");
    let tail = cut["truncated_tail_bytes"].as_u64().unwrap_or(0);
    assert!(tail > 0, "the partial record is reported: {cut}");
    assert!(
        cut["records"].as_u64() < i["records"].as_u64(),
        "only the cut record is lost: {cut} vs {i}"
    );
    assert_eq!(
        cut["records"].as_u64().map(|r| r + 1),
        i["records"].as_u64(),
        "{cut} vs {i}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The recorder's own fault: its writes fail (here the file-size limit, EFBIG, as a full disk
/// fails them with ENOSPC). The run goes on to its end, says so once, reports the error and
/// the records it could not write, and what reached the disk stays readable.
#[test]
fn a_recorder_whose_writes_fail_lets_the_run_go_on_and_stays_readable() {
    let dir = scratch("write-fails");
    let bin = env!("CARGO_BIN_EXE_gelgrip");
    // 400 blocks of 1 KiB: the first segment fails part way; SIGXFSZ is ignored, so the
    // write returns the error instead of killing the process.
    let script = format!(
        "trap '' XFSZ; ulimit -f 400; exec '{bin}' run --headless --json --clock virtual \
         --duration 3 --record '{}'",
        dir.display()
    );
    let out = Command::new("bash")
        .args(["-c", &script])
        .env("RUST_LOG", "warn")
        .output()
        .expect("runs");
    let report = common::report(&out, 0);
    assert_eq!(
        report["end_reason"], "duration",
        "the run went on: {report}"
    );
    let rec = &report["recording"];
    let error = rec["error"].as_str().unwrap_or_default();
    assert!(error.contains("File too large"), "{rec}");
    assert!(rec["dropped_io"].as_u64().unwrap_or(0) > 0, "{rec}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        stderr.matches("recording stopped").count(),
        1,
        "said once: {stderr}"
    );
    let i = info(&dir);
    assert_eq!(i["crc_errors"], 0, "every whole record checks: {i}");
    assert_eq!(i["clean_end"], false, "{i}");
    assert!(i["records"].as_u64().unwrap_or(0) > 0, "{i}");
    let _ = std::fs::remove_dir_all(&dir);
}
