//! One set of `ServoBus` test bodies, run against (a) `DynamixelBus` talking to the servo
//! emulator over a real pseudo-terminal through `dynamixel2`, and (b) an in-memory mock of
//! the port.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use gelgrip_controller::actuator::{FingerGoal, ServoBus, ServoError, ServoState};
use gelgrip_dynamixel::control_table::{addr, hardware_error};
use gelgrip_dynamixel::driver::DynamixelBus;
use gelgrip_dynamixel::emu::ServoBusEmulator;
use gelgrip_dynamixel::protocol::PacketDecoder;
use serialport::{SerialPort, TTYPort};

/// Injects a hardware fault into finger `i`'s servo.
type Inject = Box<dyn Fn(usize, u8)>;

fn goals(n: usize) -> Vec<FingerGoal> {
    (0..n)
        .map(|i| FingerGoal {
            position_deg: 90.0 + i as f64,
            goal_current_ma: 300.0,
            profile_velocity_rpm: 20.0,
        })
        .collect()
}

fn bodies(bus: &mut dyn ServoBus, inject: Inject) {
    bus.configure().expect("configure");
    let s = bus.read_state().expect("state");
    assert_eq!(s.len(), bus.fingers());
    assert!(s.iter().all(|s| s.hardware_error == 0));
    assert!(matches!(
        bus.write_goals(&goals(bus.fingers() + 1)),
        Err(ServoError::Invalid(_))
    ));
    bus.write_goals(&goals(bus.fingers())).expect("goals");
    inject(1, hardware_error::OVERLOAD);
    let s = bus
        .read_state()
        .expect("an overload is recovered by reboot");
    assert_eq!(s[1].hardware_error, 0);
    bus.set_torque(false).expect("torque off");
}

struct Emulated {
    path: String,
    emu: Arc<Mutex<ServoBusEmulator>>,
    stop: Arc<AtomicBool>,
    _slave: TTYPort,
}

fn emulate(ids: &[u8]) -> Emulated {
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
                    let replies = emu.lock().map(|mut e| e.handle(&p)).unwrap_or_default();
                    for r in replies {
                        let _ = master.write_all(&r.encode());
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

#[test]
fn dynamixel_bus_on_the_emulator() {
    let ids = [1u8, 2, 3];
    let e = emulate(&ids);
    let mut bus = DynamixelBus::open(&e.path, 1_000_000, &ids, 1000.0).expect("open");
    let emu = e.emu.clone();
    bodies(
        &mut bus,
        Box::new(move |finger, bits| {
            if let Ok(mut em) = emu.lock()
                && let Some(s) = em.servo_mut(ids[finger])
            {
                s.inject_hardware_error(bits);
            }
        }),
    );
    // The configuration reached the servos: mode 5, and the goals' current cap.
    let mut em = e.emu.lock().expect("emulator");
    let s = em.servo_mut(3).expect("servo 3");
    assert_eq!(s.bytes(addr::OPERATING_MODE, 1), Some(&[5u8][..]));
    assert_eq!(
        s.bytes(addr::GOAL_CURRENT, 2),
        Some(&112u16.to_le_bytes()[..])
    ); // 300 mA / 2.69
    e.stop.store(true, Ordering::SeqCst);
}

#[test]
fn a_missing_servo_is_a_timeout() {
    let e = emulate(&[1, 2]);
    let mut bus = DynamixelBus::open(&e.path, 1_000_000, &[1, 2, 7], 1000.0).expect("open");
    match bus.configure() {
        Err(ServoError::Timeout { id: 7, .. }) => {}
        other => panic!("expected a timeout from servo 7, got {other:?}"),
    }
    e.stop.store(true, Ordering::SeqCst);
}

/// The in-memory mock of the port: same semantics, no wire.
#[derive(Default)]
struct MockBus {
    states: Vec<ServoState>,
    faults: Arc<Mutex<Vec<u8>>>,
    torque: bool,
}

impl ServoBus for MockBus {
    fn fingers(&self) -> usize {
        self.states.len()
    }
    fn configure(&mut self) -> Result<(), ServoError> {
        self.torque = true;
        Ok(())
    }
    fn set_torque(&mut self, on: bool) -> Result<(), ServoError> {
        self.torque = on;
        Ok(())
    }
    fn write_goals(&mut self, goals: &[FingerGoal]) -> Result<(), ServoError> {
        if goals.len() != self.states.len() {
            return Err(ServoError::Invalid(format!(
                "{} goals for {} servos",
                goals.len(),
                self.states.len()
            )));
        }
        Ok(())
    }
    fn read_state(&mut self) -> Result<Vec<ServoState>, ServoError> {
        for f in 0..self.states.len() {
            if self.faults.lock().map(|v| v[f]).unwrap_or(0) != 0 {
                self.reboot(f)?;
            }
        }
        Ok(self.states.clone())
    }
    fn reboot(&mut self, finger: usize) -> Result<(), ServoError> {
        if let Ok(mut v) = self.faults.lock() {
            v[finger] = 0;
        }
        Ok(())
    }
}

#[test]
fn mock_bus() {
    let faults = Arc::new(Mutex::new(vec![0u8; 3]));
    let mut bus = MockBus {
        states: vec![ServoState::default(); 3],
        faults: faults.clone(),
        torque: false,
    };
    bodies(
        &mut bus,
        Box::new(move |finger, bits| {
            if let Ok(mut v) = faults.lock() {
                v[finger] = bits;
            }
        }),
    );
}
