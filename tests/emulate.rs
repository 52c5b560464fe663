//! `gelgrip emulate servos` end to end: the CLI contract (link after serving, one JSON line,
//! link removed on SIGTERM) and a real Protocol 2.0 client (`dynamixel2`) on the link.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

#[test]
fn dynamixel2_talks_to_the_emulated_servos_through_the_link() {
    let dir = std::env::temp_dir().join(format!("gelgrip-emu-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let link = dir.join("dxl");
    let _ = std::fs::remove_file(&link);
    let mut child = Command::new(env!("CARGO_BIN_EXE_gelgrip"))
        .args([
            "emulate",
            "servos",
            "--link",
            link.to_str().expect("utf-8"),
            "--ids",
            "1,2,3",
        ])
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .spawn()
        .expect("emulator starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("one JSON line");
    let v: serde_json::Value = serde_json::from_str(&line).expect("JSON");
    assert_eq!(v["link"], link.to_str().expect("utf-8"));
    assert!(
        v["pty"]
            .as_str()
            .is_some_and(|p| p.starts_with("/dev/pts/")),
        "{v}"
    );
    assert!(link.exists(), "the link exists once the line is printed");

    for _reopen in 0..2 {
        let mut bus = dynamixel2::Bus::open(&link, 1_000_000).expect("bus opens on the link");
        for id in 1..=3 {
            assert_eq!(bus.ping(id).expect("ping").data.model, 1020);
        }
        assert!(bus.ping(9).is_err(), "no servo 9: a timeout");
        let found: Vec<u8> = bus
            .scan()
            .expect("scan")
            .into_iter()
            .filter_map(Result::ok)
            .map(|r| r.motor_id)
            .collect();
        assert_eq!(found, vec![1, 2, 3]);
        bus.write_u8(2, 64, 1).expect("torque on");
        let err = bus
            .write_u8(2, 11, 5)
            .expect_err("EEPROM write with torque on");
        assert!(err.to_string().contains("0x7"), "{err}");
        bus.write_u8(2, 64, 0).expect("torque off");
        let pos: Vec<u32> = bus
            .sync_read_u32(&[1, 2, 3], 132)
            .expect("sync read")
            .into_iter()
            .map(|r| r.data)
            .collect();
        assert_eq!(pos.len(), 3);
        drop(bus); // the client closes; the next loop reopens the port
    }

    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success());
    let exit = child.wait().expect("emulator exits");
    assert!(exit.success(), "{exit:?}");
    assert!(!link.exists(), "the link is removed on SIGTERM");
}
