//! Servo faults on the simulated bus: an overload from straining against the object is
//! recovered by a reboot and reported; a motor that stays too hot is a typed, unrecovered
//! `HardwareFault` after the bounded retries.

use gelgrip_controller::actuator::{FingerGoal, MAX_RECOVERY_TRIES, ServoBus, ServoError};
use gelgrip_controller::clock::VirtualClock;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::motor::Xm430Motor;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::servo_bus::SimServoBus;
use gelgrip_sim::world::World;

fn world() -> World {
    let layout = HandLayout::from_toml(
        "three-finger.toml",
        include_str!("../../../configs/layouts/three-finger.toml"),
    )
    .expect("layout");
    let text = include_str!("../../../configs/scenes/egg.toml");
    let scene = SceneSpec::from_toml("egg.toml", text, &layout).expect("scene");
    World::new(&layout, Some(scene))
}

fn squeeze(current_ma: f64) -> Vec<FingerGoal> {
    vec![
        FingerGoal {
            position_deg: 180.0,
            goal_current_ma: current_ma,
            profile_velocity_rpm: 0.0,
        };
        3
    ]
}

#[test]
fn an_overload_is_recovered_by_reboot_and_reported() {
    let clock = VirtualClock::new();
    let world = world().into_shared();
    let mut bus = SimServoBus::new(world, clock.clone(), &[1, 2, 3], 2300.0).expect("bus");
    bus.configure().expect("configure");
    bus.write_goals(&squeeze(2000.0)).expect("goals");
    clock.advance(4_000_000);
    let states = bus.read_state().expect("recovered");
    assert!(states.iter().all(|s| s.hardware_error == 0), "{states:?}");
    let recovered = bus.take_recovered();
    assert_eq!(recovered.len(), 3, "{recovered:?}");
    assert!(recovered.iter().all(|r| r.bits == 1 << 5 && r.tries == 1));
    assert!(
        recovered[0].to_string().contains("overload"),
        "{}",
        recovered[0]
    );
    assert!(bus.take_recovered().is_empty(), "reported once");
}

#[test]
fn a_motor_that_stays_hot_is_an_unrecovered_hardware_fault() {
    let clock = VirtualClock::new();
    let mut w = world();
    w.set_motor(1, Xm430Motor::default().with_temperature(90.0));
    let mut bus =
        SimServoBus::new(w.into_shared(), clock.clone(), &[1, 2, 3], 2300.0).expect("bus");
    bus.configure().expect("configure");
    bus.write_goals(&squeeze(300.0)).expect("goals");
    clock.advance(100_000);
    match bus.read_state() {
        Err(ServoError::HardwareFault { id, bits, tries }) => {
            assert_eq!((id, bits, tries), (2, 1 << 2, MAX_RECOVERY_TRIES));
        }
        other => panic!("expected a hardware fault, got {other:?}"),
    }
}

#[test]
fn goals_are_checked_and_capped() {
    let clock = VirtualClock::new();
    let mut bus =
        SimServoBus::new(world().into_shared(), clock.clone(), &[1, 2, 3], 500.0).expect("bus");
    assert!(matches!(
        bus.write_goals(&squeeze(100.0)[..2]),
        Err(ServoError::Invalid(_))
    ));
    bus.configure().expect("configure");
    bus.write_goals(&squeeze(5000.0)).expect("goals");
    clock.advance(3_000_000);
    let states = bus.read_state().expect("state");
    assert!(
        states.iter().all(|s| s.current_ma <= 500.0 + 1e-9),
        "{states:?}"
    );
    assert!(SimServoBus::new(world().into_shared(), clock, &[1, 2], 500.0).is_err());
}
