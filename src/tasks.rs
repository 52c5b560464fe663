//! What drives the gripper in a run: the built-in gentle grasp, a task script, or (no
//! task, with the dashboard) the idle gripper that the grasp API commands; behind one face
//! for the run loop.

use gelgrip_controller::actuator::ServoState;
use gelgrip_controller::frame::FrameSet;

use gelgrip_controller::grasp::Phase;

use crate::grasp_task::{GraspTask, TaskReport};
use crate::gripper_loop::GripperLoop;
use crate::script_task::ScriptTask;
use crate::task_io::TaskIo;

/// A running task.
pub enum Task {
    /// `--task gentle-grasp`.
    Grasp(GraspTask),
    /// `--task FILE|NAME`, a script.
    Script(ScriptTask),
    /// No task: the dashboard's commands drive the gripper.
    Idle(GripperLoop),
}

impl Task {
    /// Handle one gated set; returns an end reason when the task ends.
    pub fn on_set(&mut self, set: &FrameSet, now_us: u64) -> anyhow::Result<Option<&'static str>> {
        match self {
            Self::Grasp(t) => t.on_set(set, now_us),
            Self::Script(t) => t.on_set(set, now_us),
            Self::Idle(t) => t.on_set(set, now_us).map(|()| None),
        }
    }

    /// Check the watchdog; a fault description when it fires (the fingers hold).
    pub fn watchdog(&mut self, now_us: u64) -> Option<String> {
        match self {
            Self::Grasp(t) => t.watchdog(now_us),
            Self::Script(t) => t.watchdog(now_us),
            Self::Idle(t) => {
                let silent_ms = t.io_mut().watchdog_silence_ms(now_us)?;
                let _ = t.handle().stop();
                t.apply_urgent();
                Some(format!(
                    "watchdog: no synchronized set for {silent_ms} ms; fingers hold"
                ))
            }
        }
    }

    /// E-stop: hold at the minimum current.
    pub fn estop(&mut self) {
        match self {
            Self::Grasp(t) => t.estop(),
            Self::Script(t) => t.estop(),
            Self::Idle(t) => t.estop(),
        }
    }

    /// The safe state at the end of the run: torque off (the springs open the fingers).
    pub fn finish(&mut self) {
        if let Self::Script(t) = self {
            t.interrupt();
        }
        self.io_mut().finish();
    }

    /// Recovered servo faults (taken).
    pub fn take_recovered(&mut self) -> Vec<String> {
        std::mem::take(&mut self.io_mut().recovered)
    }

    /// The servos' last states.
    pub fn states(&self) -> &[ServoState] {
        self.io().states()
    }

    /// The hardware side.
    pub fn io(&self) -> &TaskIo {
        match self {
            Self::Grasp(t) => t.io(),
            Self::Script(t) => t.io(),
            Self::Idle(t) => t.io(),
        }
    }

    fn io_mut(&mut self) -> &mut TaskIo {
        match self {
            Self::Grasp(t) => t.io_mut(),
            Self::Script(t) => t.io_mut(),
            Self::Idle(t) => t.io_mut(),
        }
    }

    /// The task fields of the run report (none for the idle gripper).
    pub fn report(&self) -> Option<TaskReport> {
        match self {
            Self::Grasp(t) => Some(t.report()),
            Self::Script(t) => Some(t.report()),
            Self::Idle(_) => None,
        }
    }

    /// Each finger's phase, regulated force and target, N.
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        match self {
            Self::Grasp(t) => t.fingers(),
            Self::Script(t) => t.fingers(),
            Self::Idle(t) => t.fingers(),
        }
    }

    /// The task's name and stage (none for the idle gripper).
    pub fn stage(&self) -> Option<(String, String)> {
        match self {
            Self::Grasp(t) => Some(("gentle-grasp".into(), t.stage_label().into())),
            Self::Script(t) => Some(t.stage()),
            Self::Idle(_) => None,
        }
    }
}
