//! What drives the gripper in a run: the built-in gentle grasp, or the
//! [`GripperLoop`] (the grasp API, and the task scripts that `--task` or the dashboard
//! start); behind one face for the run loop.

use gelgrip_controller::actuator::ServoState;
use gelgrip_controller::frame::FrameSet;

use gelgrip_controller::grasp::Phase;

use crate::grasp_task::{GraspTask, TaskReport};
use crate::gripper_loop::{GripperLoop, ScriptEnd};
use crate::task_io::TaskIo;
use gelgrip_web::live::TaskView;

/// A running task.
pub enum Task {
    /// `--task gentle-grasp`.
    Grasp(Box<GraspTask>),
    /// The grasp API and task scripts.
    Gripper {
        /// The gripper (boxed: it carries the running and the last script).
        gripper: Box<GripperLoop>,
        /// `--task FILE|NAME`: the run ends with the script (else it goes on, and the
        /// dashboard drives the gripper).
        script_ends_run: bool,
    },
}

/// The run's end reason when a script ended, if it ends the run.
fn script_end_reason(end: Option<ScriptEnd>, ends_run: bool) -> Option<&'static str> {
    match end? {
        ScriptEnd::Estop => Some("estop").filter(|_| ends_run),
        ScriptEnd::Finished | ScriptEnd::Interrupted => Some("done").filter(|_| ends_run),
    }
}

impl Task {
    /// The task's pipelines.
    pub fn tactile_mut(&mut self) -> &mut crate::tactile::Tactile {
        match self {
            Self::Grasp(t) => t.io_mut().tactile_mut(),
            Self::Gripper { gripper, .. } => gripper.io_mut().tactile_mut(),
        }
    }

    /// Handle one gated set; returns an end reason when the task ends.
    pub fn on_set(&mut self, set: &FrameSet, now_us: u64) -> anyhow::Result<Option<&'static str>> {
        match self {
            Self::Grasp(t) => t.on_set(set, now_us),
            Self::Gripper {
                gripper,
                script_ends_run,
            } => Ok(script_end_reason(
                gripper.on_set(set, now_us)?,
                *script_ends_run,
            )),
        }
    }

    /// Commands queued between sets are applied now; returns an end reason when they
    /// ended the run's script.
    pub fn apply_urgent(&mut self) -> Option<&'static str> {
        match self {
            Self::Grasp(_) => None,
            Self::Gripper {
                gripper,
                script_ends_run,
            } => script_end_reason(gripper.apply_urgent(), *script_ends_run),
        }
    }

    /// Check the watchdog; when it fires, every finger holds, and the fault's description
    /// comes back with whether it ends the run. A `--task` run ends; the dashboard's gripper
    /// holds until sets come back and carries on (it fires once per silence).
    pub fn watchdog(&mut self, now_us: u64) -> Option<(String, bool)> {
        match self {
            Self::Grasp(t) => t.watchdog(now_us).map(|f| (f, true)),
            Self::Gripper {
                gripper,
                script_ends_run,
            } => {
                let silent_ms = gripper.io_mut().watchdog_silence_ms(now_us)?;
                if !*script_ends_run && gripper.watchdog_holding {
                    return None;
                }
                let reason =
                    format!("watchdog: no synchronized set for {silent_ms} ms; fingers hold");
                gripper.hold(&reason);
                gripper.watchdog_holding = true;
                Some((reason, *script_ends_run))
            }
        }
    }

    /// E-stop: hold at the minimum current.
    pub fn estop(&mut self) {
        match self {
            Self::Grasp(t) => t.estop(),
            Self::Gripper { gripper, .. } => gripper.estop(),
        }
    }

    /// The safe state at the end of the run: torque off (the springs open the fingers).
    pub fn finish(&mut self) {
        if let Self::Gripper { gripper, .. } = self {
            gripper.interrupt();
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
            Self::Gripper { gripper, .. } => gripper.io(),
        }
    }

    fn io_mut(&mut self) -> &mut TaskIo {
        match self {
            Self::Grasp(t) => t.io_mut(),
            Self::Gripper { gripper, .. } => gripper.io_mut(),
        }
    }

    /// The task fields of the run report (none without `--task`).
    pub fn report(&self) -> Option<TaskReport> {
        match self {
            Self::Grasp(t) => Some(t.report()),
            Self::Gripper {
                gripper,
                script_ends_run: true,
            } => gripper.script_report(),
            Self::Gripper { .. } => None,
        }
    }

    /// Each finger's phase, regulated force and target, N.
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        match self {
            Self::Grasp(t) => t.fingers(),
            Self::Gripper { gripper, .. } => gripper.fingers(),
        }
    }

    /// The task for the page (the running or last script's; none before any).
    pub fn view(&self) -> Option<TaskView> {
        match self {
            Self::Grasp(t) => {
                let stage = t.stage_label();
                Some(TaskView {
                    name: "gentle-grasp".into(),
                    stage: stage.into(),
                    running: stage != "done",
                    outcome: (stage == "done").then(|| t.report().reason),
                })
            }
            Self::Gripper { gripper, .. } => {
                gripper.stage().map(|(name, stage, outcome)| TaskView {
                    name,
                    stage,
                    running: gripper.running_script().is_some(),
                    outcome,
                })
            }
        }
    }

    fn service_mut(&mut self) -> &mut gelgrip_controller::gripper::GripperService {
        match self {
            Self::Grasp(t) => t.service_mut(),
            Self::Gripper { gripper, .. } => gripper.service_mut(),
        }
    }

    /// Log the grasp-API service's commands and steps (for a recording).
    pub fn log_controller(&mut self) {
        self.service_mut().log_events();
    }

    /// The service's commands and steps since the last call (empty when not logging).
    pub fn take_controller_events(&mut self) -> Vec<gelgrip_controller::gripper::ServiceEvent> {
        self.service_mut().take_events()
    }

    /// The grasp API's handle.
    pub fn handle(&self) -> gelgrip_controller::gripper::GripperHandle {
        match self {
            Self::Grasp(t) => t.handle(),
            Self::Gripper { gripper, .. } => gripper.handle(),
        }
    }
}
