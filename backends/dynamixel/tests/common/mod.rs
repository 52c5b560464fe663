//! Shared by the crate's integration tests: the `ServoBus` test bodies (run on the emulator,
//! on the mock and on real servos) and the servo emulator served on a real pseudo-terminal.

#![allow(dead_code)] // each test file uses its own subset

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gelgrip_controller::actuator::{FingerGoal, ServoBus, ServoError, ServoState};
use gelgrip_dynamixel::emu::ServoBusEmulator;
use gelgrip_dynamixel::protocol::PacketDecoder;
use serialport::{SerialPort, TTYPort};

/// Goal current of the test moves, mA: low, safe on a real gripper.
pub const LOW_CURRENT_MA: f64 = 100.0;
/// Size of the test move, degrees.
pub const SMALL_MOVE_DEG: f64 = 5.0;

/// One goal per finger: `from` plus [`SMALL_MOVE_DEG`], at [`LOW_CURRENT_MA`], slowly.
pub fn small_move(from: &[ServoState]) -> Vec<FingerGoal> {
    from.iter()
        .map(|s| FingerGoal {
            position_deg: s.position_deg + SMALL_MOVE_DEG,
            goal_current_ma: LOW_CURRENT_MA,
            profile_velocity_rpm: 5.0,
        })
        .collect()
}

/// The body that is safe on real servos: configure, read state, reject a wrong goal count,
/// a small slow move at low current, read state again, torque off. Returns the last state.
pub fn configure_move_release(bus: &mut dyn ServoBus) -> Vec<ServoState> {
    bus.configure().expect("configure");
    let start = bus.read_state().expect("state");
    assert_eq!(start.len(), bus.fingers());
    for s in &start {
        assert_eq!(s.hardware_error, 0, "{s:?}");
        assert!((0.0..=80.0).contains(&s.temperature_c), "{s:?}");
    }
    let mut goals = small_move(&start);
    goals.push(goals[0]);
    assert!(matches!(
        bus.write_goals(&goals),
        Err(ServoError::Invalid(_))
    ));
    bus.write_goals(&small_move(&start)).expect("goals");
    std::thread::sleep(Duration::from_millis(300));
    let end = bus.read_state().expect("state after the move");
    assert_eq!(end.len(), bus.fingers());
    bus.set_torque(false).expect("torque off");
    end
}

/// The emulator served on the master end of a pseudo-terminal pair, until dropped.
pub struct Emulated {
    /// The slave end's path, for the client.
    pub path: String,
    /// The emulated servos (for fault injection and inspection).
    pub emu: Arc<Mutex<ServoBusEmulator>>,
    stop: Arc<AtomicBool>,
    _slave: TTYPort,
}

impl Drop for Emulated {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

/// Serve factory-fresh servos `ids` (no motor) on a new pseudo-terminal.
pub fn emulate(ids: &[u8]) -> Emulated {
    let (mut master, slave) = TTYPort::pair().expect("pty pair");
    master
        .set_timeout(Duration::from_millis(10))
        .expect("timeout");
    let emu = Arc::new(Mutex::new(ServoBusEmulator::new(ids)));
    let stop = Arc::new(AtomicBool::new(false));
    std::thread::spawn({
        let (emu, stop) = (emu.clone(), stop.clone());
        move || {
            let mut dec = PacketDecoder::new();
            let mut buf = [0u8; 512];
            while !stop.load(Ordering::SeqCst) {
                match master.read(&mut buf) {
                    Ok(n) => dec.push(&buf[..n]),
                    Err(_) => continue,
                }
                while let Some(Ok(p)) = dec.next_packet() {
                    let replies = emu.lock().map(|mut e| e.respond(&p)).unwrap_or_default();
                    for r in replies {
                        let _ = master.write_all(&r);
                    }
                }
            }
        }
    });
    Emulated {
        path: slave.name().expect("path"),
        emu,
        stop,
        _slave: slave,
    }
}

/// Run `f` on servo `id` of the emulator.
pub fn on_servo(e: &Emulated, id: u8, f: impl FnOnce(&mut gelgrip_dynamixel::emu::EmulatedServo)) {
    let mut em = e.emu.lock().expect("emulator");
    f(em.servo_mut(id).expect("servo"));
}
