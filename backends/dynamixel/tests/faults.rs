//! Servo faults through `DynamixelBus` on the emulator over a real pseudo-terminal:
//! overheating recovered by reboot, overheating that every reboot raises again (a hardware
//! fault after `MAX_RECOVERY_TRIES`), and a disconnect mid-transfer (a reply cut off, then
//! silence) that must end in a typed error within the driver's deadline, not a hang.

use std::time::{Duration, Instant};

use gelgrip_controller::actuator::{ServoBus, ServoError};
use gelgrip_dynamixel::control_table::{addr, hardware_error::OVERHEATING};
use gelgrip_dynamixel::driver::{DynamixelBus, MAX_RECOVERY_TRIES};

mod common;

const IDS: [u8; 3] = [1, 2, 3];
/// Generous bound on one failed call: the documented deadline is the reply's wire time plus
/// 34 ms per awaited status packet (about 0.1 s for a sync read of three servos).
const MAX_FAILED_CALL: Duration = Duration::from_secs(2);

fn configured() -> (common::Emulated, DynamixelBus) {
    let e = common::emulate(&IDS);
    let mut bus = DynamixelBus::open(&e.path, 1_000_000, &IDS, 500.0).expect("open");
    bus.configure().expect("configure");
    (e, bus)
}

fn torque_of(e: &common::Emulated, id: u8) -> u8 {
    let mut torque = 0;
    common::on_servo(e, id, |s| {
        torque = s.bytes(addr::TORQUE_ENABLE, 1).map_or(0, |b| b[0]);
    });
    torque
}

#[test]
fn overheating_is_recovered_by_reboot() {
    let (e, mut bus) = configured();
    common::on_servo(&e, 2, |s| s.inject_hardware_error(OVERHEATING));
    assert_eq!(torque_of(&e, 2), 0, "overheating is a shutdown fault");
    let s = bus.read_state().expect("recovered by a reboot");
    assert!(s.iter().all(|s| s.hardware_error == 0), "{s:?}");
    assert_eq!(torque_of(&e, 2), 1, "reconfigured after the reboot");
}

#[test]
fn persistent_overheating_is_a_hardware_fault_after_the_tries() {
    let (e, mut bus) = configured();
    common::on_servo(&e, 2, |s| s.set_stuck_hardware_error(OVERHEATING));
    match bus.read_state() {
        Err(ServoError::HardwareFault { id: 2, bits, tries }) => {
            assert_eq!(bits, OVERHEATING);
            assert_eq!(tries, MAX_RECOVERY_TRIES);
        }
        other => panic!("expected a hardware fault on servo 2, got {other:?}"),
    }
    common::on_servo(&e, 2, |s| s.set_stuck_hardware_error(0));
    bus.read_state()
        .expect("once the servo cools, the next read recovers it");
}

/// Cut the next reply to `keep` bytes, run `call`, check that it fails with a typed error in
/// time, and return the error.
fn cut_reply(
    e: &common::Emulated,
    keep: usize,
    call: impl FnOnce() -> Result<(), ServoError>,
) -> ServoError {
    e.emu.lock().expect("emulator").cut_next_reply(keep);
    let t0 = Instant::now();
    let result = call();
    let elapsed = t0.elapsed();
    assert!(
        elapsed < MAX_FAILED_CALL,
        "reply cut at {keep} bytes: took {elapsed:?}"
    );
    match result {
        Err(e @ (ServoError::Timeout { .. } | ServoError::Corrupt { .. } | ServoError::Bus(_))) => {
            e
        }
        other => panic!("reply cut at {keep} bytes: {other:?}"),
    }
}

#[test]
fn a_disconnect_mid_transfer_is_a_typed_error_in_time_and_the_bus_recovers() {
    let (e, mut bus) = configured();
    // The state reply is 88 bytes: cut in the header, in the body, and before the CRC.
    for keep in [0, 4, 9, 40, 86] {
        let err = cut_reply(&e, keep, || bus.read_state().map(drop));
        assert!(
            matches!(err, ServoError::Timeout { id: 1, .. }),
            "the cut reply was servo 1's: {err:?}"
        );
        let s = bus.read_state().expect("the next read succeeds");
        assert_eq!(s.len(), IDS.len());
    }
    // A write's reply (11 bytes) cut mid-packet.
    cut_reply(&e, 6, || bus.set_torque(false));
    bus.set_torque(true).expect("the next write succeeds");
    assert_eq!(torque_of(&e, 3), 1);
}
