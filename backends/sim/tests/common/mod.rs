//! What the simulator's scene tests share: the three-finger layout and closing the fingers.

use gelgrip_controller::actuator::MotorCommand;
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::world::World;

/// The three-finger layout of `configs/layouts`.
pub fn layout() -> HandLayout {
    let text = include_str!("../../../../configs/layouts/three-finger.toml");
    HandLayout::from_toml("three-finger.toml", text).expect("layout")
}

/// Command every finger to close fully with `current_ma` as the cap.
pub fn close_all(world: &mut World, current_ma: f64) {
    for f in 0..world.fingers() {
        world.set_command(
            f,
            MotorCommand {
                torque_on: true,
                goal_position_deg: 180.0,
                goal_current_ma: current_ma,
                profile_velocity_rpm: 0.0,
            },
        );
    }
}
