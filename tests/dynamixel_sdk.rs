//! ROBOTIS's own Protocol 2.0 client, the PyPI `dynamixel-sdk` 4.1.0, against
//! `gelgrip emulate servos`: `tests/python/dxl_sdk_conformance.py` pings, broadcast-pings,
//! reads and writes registers, checks the EEPROM lock and an out-of-range read, sync-writes
//! a goal and sync-reads the motion towards it, bulk-reads and bulk-writes a different
//! register per servo, and reboots.
//!
//! The interpreter comes from `GELGRIP_PYTHON`; `scripts/test` makes `target/pyenv` with the
//! SDK and runs this test. A missing variable or module fails loudly.

use std::process::Command;

mod common;

const FIX: &str = "run scripts/test (it creates target/pyenv with dynamixel-sdk==4.1.0), or set \
                   GELGRIP_PYTHON to a python with `pip install dynamixel-sdk==4.1.0`";

fn python() -> String {
    let python = std::env::var("GELGRIP_PYTHON")
        .unwrap_or_else(|_| panic!("GELGRIP_PYTHON is not set: {FIX}"));
    let probe = Command::new(&python)
        .args(["-c", "import dynamixel_sdk"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run GELGRIP_PYTHON={python}: {e}; {FIX}"));
    assert!(
        probe.status.success(),
        "{python} cannot import dynamixel_sdk: {}; {FIX}",
        String::from_utf8_lossy(&probe.stderr)
    );
    python
}

#[test]
#[ignore = "needs the PyPI dynamixel-sdk: run scripts/test"]
fn robotis_dynamixel_sdk_accepts_the_emulated_servos() {
    let python = python();
    let emu = common::ServoEmulator::start("dxl-sdk", "1,2,3", 1_000_000);
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/python/dxl_sdk_conformance.py"
    );
    let out = Command::new(&python)
        .args([script, emu.path(), "--baud", "1000000", "--ids", "1,2,3"])
        .output()
        .expect("the conformance script runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "exit {:?}\nstderr: {}\nstdout: {stdout}",
        out.status.code(),
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_str(&stdout).expect("one JSON summary");
    assert_eq!(summary["ok"], true, "{summary}");
    assert_eq!(summary["passed"], 8, "{summary}");
    assert_eq!(
        summary["checks"]["broadcast_ping"]["found"],
        serde_json::json!([1, 2, 3])
    );
    emu.stop();
}
