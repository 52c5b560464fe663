//! One set of `ServoBus` test bodies, run against (a) `DynamixelBus` talking to the servo
//! emulator over a real pseudo-terminal through `dynamixel2`, and (b) an in-memory mock of
//! the port.

use std::sync::{Arc, Mutex};

use gelgrip_controller::actuator::{FingerGoal, ServoBus, ServoError, ServoState};
use gelgrip_dynamixel::control_table::{addr, hardware_error};
use gelgrip_dynamixel::driver::DynamixelBus;

mod common;

/// Injects a hardware fault into finger `i`'s servo.
type Inject = Box<dyn Fn(usize, u8)>;

/// The hardware-safe body, then an injected overload that a reboot recovers.
fn bodies(bus: &mut dyn ServoBus, inject: Inject) {
    common::configure_move_release(bus);
    inject(1, hardware_error::OVERLOAD);
    let s = bus
        .read_state()
        .expect("an overload is recovered by reboot");
    assert_eq!(s[1].hardware_error, 0);
    bus.set_torque(false).expect("torque off");
}

#[test]
fn dynamixel_bus_on_the_emulator() {
    let ids = [1u8, 2, 3];
    let e = common::emulate(&ids);
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
        Some(&37u16.to_le_bytes()[..])
    ); // 100 mA / 2.69
}

#[test]
fn a_missing_servo_is_a_timeout() {
    let e = common::emulate(&[1, 2]);
    let mut bus = DynamixelBus::open(&e.path, 1_000_000, &[1, 2, 7], 1000.0).expect("open");
    match bus.configure() {
        Err(ServoError::Timeout { id: 7, .. }) => {}
        other => panic!("expected a timeout from servo 7, got {other:?}"),
    }
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
