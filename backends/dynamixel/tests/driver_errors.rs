//! What the driver makes of what servos report, through its real read path (the serial port
//! on a pseudo-terminal): a status packet shorter than its header claims is a typed error
//! and never a panic; Data Limit and Access errors name the servo, the register and the
//! value; Fast Sync Read is used where the servos answer it; a brown-out is reported.

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use gelgrip_controller::actuator::{FingerGoal, ServoBus, ServoError};
use gelgrip_dynamixel::control_table::addr;
use gelgrip_dynamixel::driver::{
    DriverError, DynamixelBus, STATE_BLOCK, STATE_BLOCK_LEN, state_read_bus_time_us,
};
use serialport::{SerialPort, TTYPort};

mod common;

/// A status packet from id 1 with LEN `len` and a correct CRC over what is there.
fn short_status(len: u16) -> Vec<u8> {
    let mut p = vec![0xFF, 0xFF, 0xFD, 0x00, 0x01];
    p.extend(len.to_le_bytes());
    p.push(0x55);
    if len >= 3 {
        let crc = dynamixel2::checksum::calculate_checksum(0, &p);
        p.extend(crc.to_le_bytes());
    } else {
        p.extend([0, 0, 0, 0]); // whatever follows
    }
    p
}

/// Answer the next instruction on `master` with `reply`.
fn answer_once(mut master: TTYPort, reply: Vec<u8>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let mut buf = [0u8; 64];
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(2) {
            if let Ok(n) = master.read(&mut buf)
                && n > 0
            {
                let _ = master.write_all(&reply);
                std::thread::sleep(Duration::from_millis(200));
                return;
            }
        }
    })
}

#[test]
fn a_status_shorter_than_a_status_is_a_length_error() {
    for len in [0u16, 1, 2, 3] {
        let (mut master, slave) = TTYPort::pair().expect("pty");
        master
            .set_timeout(Duration::from_millis(10))
            .expect("timeout");
        let path = slave.name().expect("path");
        let mut bus = DynamixelBus::open(&path, 1_000_000, &[1], 500.0).expect("open");
        let server = answer_once(master, short_status(len));
        let t0 = Instant::now();
        match bus.read(1, addr::PRESENT_POSITION, 4) {
            Err(DriverError::Length {
                id: 1, len: got, ..
            }) => assert_eq!(got, usize::from(len)),
            other => panic!("LEN {len}: {other:?}"),
        }
        assert!(
            t0.elapsed() < Duration::from_millis(500),
            "LEN {len}: no wait for the deadline"
        );
        server.join().expect("server");
        drop(slave);
    }
}

#[test]
fn data_limit_and_access_errors_name_servo_register_and_value() {
    let e = common::emulate(&[1, 2]);
    let mut bus = DynamixelBus::open(&e.path, 1_000_000, &[1, 2], 500.0).expect("open");
    match bus.write(2, addr::GOAL_POSITION, &5000i32.to_le_bytes()) {
        Err(DriverError::DataLimit {
            id: 2,
            register: "Goal Position",
            address: 116,
            value: 5000,
        }) => {}
        other => panic!("{other:?}"),
    }
    bus.write(1, addr::TORQUE_ENABLE, &[1]).expect("torque on");
    let err = bus
        .write(1, addr::OPERATING_MODE, &[5])
        .expect_err("EEPROM with torque on");
    assert!(
        matches!(
            err,
            DriverError::Access {
                id: 1,
                register: "Operating Mode",
                address: 11,
                value: Some(5)
            }
        ),
        "{err:?}"
    );
    let text = ServoError::from(err).to_string();
    assert!(
        text.contains("Operating Mode") && text.contains("servo 1"),
        "{text}"
    );
}

#[test]
fn fast_sync_read_is_used_and_reads_what_sync_read_does() {
    let e = common::emulate(&[1, 2, 3]);
    let mut bus = DynamixelBus::open(&e.path, 1_000_000, &[1, 2, 3], 500.0).expect("open");
    bus.configure().expect("configure");
    assert!(
        bus.uses_fast_reads(),
        "the emulated servos answer Fast Sync Read"
    );
    let fast = bus
        .fast_sync_read(&[1, 2, 3], STATE_BLOCK, STATE_BLOCK_LEN)
        .expect("fast");
    let plain = bus
        .sync_read(&[1, 2, 3], STATE_BLOCK, STATE_BLOCK_LEN)
        .expect("sync");
    let position = usize::from(addr::PRESENT_POSITION - STATE_BLOCK);
    for (f, p) in fast.iter().zip(&plain) {
        assert_eq!(f[position..position + 4], p[position..position + 4]);
    }
    let bulk = bus
        .fast_bulk_read(&[
            (1, addr::PRESENT_INPUT_VOLTAGE, 2),
            (3, addr::OPERATING_MODE, 1),
        ])
        .expect("fast bulk");
    assert_eq!(bulk, vec![vec![120, 0], vec![5]]);
    let goal = |p: f64| FingerGoal {
        position_deg: p,
        goal_current_ma: 100.0,
        profile_velocity_rpm: 0.0,
    };
    match bus.write_goals(&[goal(0.0), goal(1e9), goal(0.0)]) {
        Err(ServoError::Instruction {
            id: 2,
            error: 6,
            detail,
        }) => {
            assert!(detail.contains("Goal Position"), "{detail}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_brown_out_is_reported_with_servo_and_voltage() {
    let e = common::emulate(&[1, 2]);
    e.emu.lock().expect("emulator").set_supply_v(9.6);
    let mut bus = DynamixelBus::open(&e.path, 1_000_000, &[1, 2], 500.0).expect("open");
    bus.configure()
        .expect("configure: 9.6 V is inside the voltage limits");
    let b = bus.brown_outs();
    assert_eq!(b.iter().map(|r| r.id).collect::<Vec<_>>(), vec![1, 2]);
    assert!(b.iter().all(|r| (r.input_v - 9.6).abs() < 1e-9), "{b:?}");
    e.emu.lock().expect("emulator").set_supply_v(12.0);
    bus.configure().expect("configure");
    assert!(bus.brown_outs().is_empty());
}

#[test]
fn a_fast_sync_read_of_three_state_blocks_saves_two_return_delays_and_13_bytes() {
    let ids = [1, 2, 3];
    // Sync Read: 17-byte instruction, three 88-byte replies, three 500 µs delays (factory
    // Return Delay Time 250 × 2 µs). Fast: one reply of 8 + 3 × (77 + 4) bytes, one delay.
    let plain = state_read_bus_time_us(&ids, false, 1_000_000, 500.0);
    let fast = state_read_bus_time_us(&ids, true, 1_000_000, 500.0);
    assert!(
        (plain - (17.0 + 3.0 * 88.0) * 10.0 - 1500.0).abs() < 1e-6,
        "{plain}"
    );
    assert!(
        (fast - (17.0 + 251.0) * 10.0 - 500.0).abs() < 1e-6,
        "{fast}"
    );
    let no_delay = state_read_bus_time_us(&ids, false, 1_000_000, 0.0)
        - state_read_bus_time_us(&ids, true, 1_000_000, 0.0);
    assert!((no_delay - 130.0).abs() < 1e-6, "{no_delay}");
}
