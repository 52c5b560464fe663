//! The task a run carries out: the built-in gentle grasp or a task script, behind one face
//! for the run loop.

use gelgrip_controller::actuator::ServoState;
use gelgrip_controller::frame::FrameSet;

use crate::grasp_task::{GraspTask, TaskReport};
use crate::script_task::ScriptTask;
use crate::task_io::TaskIo;

/// A running task.
pub enum Task {
    /// `--task gentle-grasp`.
    Grasp(GraspTask),
    /// `--task FILE|NAME`, a script.
    Script(ScriptTask),
}

impl Task {
    /// Handle one gated set; returns an end reason when the task ends.
    pub fn on_set(&mut self, set: &FrameSet, now_us: u64) -> anyhow::Result<Option<&'static str>> {
        match self {
            Self::Grasp(t) => t.on_set(set, now_us),
            Self::Script(t) => t.on_set(set, now_us),
        }
    }

    /// Check the watchdog; a fault description when it fires (the fingers hold).
    pub fn watchdog(&mut self, now_us: u64) -> Option<String> {
        match self {
            Self::Grasp(t) => t.watchdog(now_us),
            Self::Script(t) => t.watchdog(now_us),
        }
    }

    /// E-stop: hold at the minimum current.
    pub fn estop(&mut self) {
        match self {
            Self::Grasp(t) => t.estop(),
            Self::Script(t) => t.estop(),
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

    fn io(&self) -> &TaskIo {
        match self {
            Self::Grasp(t) => t.io(),
            Self::Script(t) => t.io(),
        }
    }

    fn io_mut(&mut self) -> &mut TaskIo {
        match self {
            Self::Grasp(t) => t.io_mut(),
            Self::Script(t) => t.io_mut(),
        }
    }

    /// The task fields of the run report.
    pub fn report(&self) -> TaskReport {
        match self {
            Self::Grasp(t) => t.report(),
            Self::Script(t) => t.report(),
        }
    }
}
