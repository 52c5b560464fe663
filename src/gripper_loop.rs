//! The gripper when no task runs: every gated set goes through the pipelines and steps the
//! grasp API's service, so the dashboard's grasp, release, stop and e-stop act at once.
//! Until a command arrives the fingers stay where they are (no goal is written).

use gelgrip_controller::actuator::ServoBus;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::grasp::{Phase, Tuning};
use gelgrip_controller::gripper::{GripperHandle, GripperService};
use gelgrip_sim::world::SharedWorld;

use crate::task_io::TaskIo;

/// The idle gripper, driven by the grasp API.
pub struct GripperLoop {
    io: TaskIo,
    gripper: GripperService,
    handle: GripperHandle,
}

impl GripperLoop {
    /// Open the pipelines and the servos, and the grasp API's service.
    pub fn start(
        config: &AppConfig,
        bus: Box<dyn ServoBus>,
        world: Option<SharedWorld>,
    ) -> anyhow::Result<Self> {
        let io = TaskIo::open(config, bus, world, None)?;
        let close: Vec<f64> = io
            .layout
            .fingers
            .iter()
            .map(|f| f.servo_range_deg)
            .collect();
        let n = close.len();
        let (gripper, handle) = GripperService::new(
            Tuning::default(),
            close,
            vec![0.0; n],
            config.servos.current_limit_ma,
        );
        Ok(Self {
            io,
            gripper,
            handle,
        })
    }

    /// The grasp API's handle.
    pub fn handle(&self) -> GripperHandle {
        self.handle.clone()
    }

    /// Handle one gated set at host time `now_us`.
    pub fn on_set(&mut self, set: &FrameSet, now_us: u64) -> anyhow::Result<()> {
        let sensed = self.io.drive(&mut self.gripper, set, now_us)?;
        self.io.remember(sensed.fused);
        Ok(())
    }

    /// A stop or e-stop queued between sets is applied at once.
    pub fn apply_urgent(&mut self) {
        if self.gripper.apply_commands(&self.io.positions())
            && let Some(goals) = self.gripper.goals()
        {
            self.io.write_now(&goals);
        }
    }

    /// E-stop: every finger holds where it is at the minimum current.
    pub fn estop(&mut self) {
        self.io.refresh_states();
        let _ = self.handle.estop();
        self.apply_urgent();
    }

    /// Each finger's phase, force and target (before any command: open, 0, 0).
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        let n = self.io.layout.fingers.len();
        self.gripper
            .controller()
            .map_or_else(|| vec![(Phase::Open, 0.0, 0.0); n], |c| c.finger_states())
    }

    /// The hardware side.
    pub fn io(&self) -> &TaskIo {
        &self.io
    }

    /// The hardware side, mutably.
    pub fn io_mut(&mut self) -> &mut TaskIo {
        &mut self.io
    }
}
