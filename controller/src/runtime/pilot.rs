//! What drives the gripper in a run, behind one face for the runtime: the built-in gentle
//! grasp, or the [`CommandedGripper`] (the grasp API, and the task scripts that `--task` or
//! the dashboard start).

use crate::actuator::ServoState;
use crate::frame::FrameSet;
use crate::grasp::Phase;
use crate::gripper::{GripperHandle, GripperService, ServiceEvent};
use crate::runtime::commanded::CommandedGripper;
use crate::runtime::gentle_grasp::{GentleGrasp, TASK_NAME};
use crate::runtime::outcome::{EndReason, FaultLog, ScriptEnd};
use crate::runtime::plant::Plant;
use crate::runtime::ports::{PilotControl, Sensing};
use crate::runtime::report::DrivenSet;
use crate::runtime::task_report::{TaskReport, TaskStatus};
use crate::task::TaskScript;

/// Whoever drives the fingers in a run.
#[derive(Debug)]
pub enum Pilot {
    /// `--task gentle-grasp`.
    GentleGrasp(Box<GentleGrasp>),
    /// The grasp API and task scripts.
    Commanded {
        /// The gripper (boxed: it carries the running and the last script).
        gripper: Box<CommandedGripper>,
        /// `--task FILE|NAME`: the run ends with the script (else it goes on, and the
        /// dashboard drives the gripper).
        script_ends_run: bool,
    },
}

/// The run's end reason when a script ended, if it ends the run.
fn script_end_reason(end: Option<ScriptEnd>, ends_run: bool) -> Option<EndReason> {
    match end? {
        ScriptEnd::Estop => Some(EndReason::Estop).filter(|_| ends_run),
        ScriptEnd::Finished | ScriptEnd::Interrupted => Some(EndReason::Done).filter(|_| ends_run),
    }
}

impl Pilot {
    /// Handle one gated set, sensed through `sensing`: what the pilot did with it, with an
    /// end reason when the task ends.
    pub fn on_set(&mut self, sensing: &mut dyn Sensing, set: &FrameSet, now_us: u64) -> DrivenSet {
        let mut driven = match self {
            Self::GentleGrasp(t) => t.on_set(sensing, set, now_us),
            Self::Commanded {
                gripper,
                script_ends_run,
            } => match gripper.on_set(sensing, set, now_us) {
                Ok(pass) => DrivenSet {
                    sensed: pass.sensed,
                    step: pass.step,
                    controller_events: Vec::new(),
                    end: Ok(script_end_reason(pass.end, *script_ends_run)),
                },
                Err(e) => DrivenSet::without_step(Err(e)),
            },
        };
        driven.controller_events = self.take_controller_events();
        driven
    }

    /// Commands queued between sets are applied now; returns an end reason when they
    /// ended the run's script.
    pub fn apply_urgent(&mut self) -> Option<EndReason> {
        match self {
            Self::GentleGrasp(_) => None,
            Self::Commanded {
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
            Self::GentleGrasp(t) => t.watchdog(now_us).map(|f| (f, true)),
            Self::Commanded {
                gripper,
                script_ends_run,
            } => {
                let silent_ms = gripper.plant_mut().watchdog_silence_ms(now_us)?;
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
            Self::GentleGrasp(t) => t.estop(),
            Self::Commanded { gripper, .. } => gripper.estop(),
        }
    }

    /// The safe state at the end of the run: torque off (the springs open the fingers).
    pub fn finish(&mut self) {
        if let Self::Commanded { gripper, .. } = self {
            gripper.interrupt();
        }
        self.plant_mut().finish();
    }

    /// Recovered servo faults (taken).
    pub fn take_recovered(&mut self) -> FaultLog {
        std::mem::take(&mut self.plant_mut().recovered)
    }

    /// The servos' last states.
    pub fn states(&self) -> &[ServoState] {
        self.plant().states()
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        match self {
            Self::GentleGrasp(t) => t.plant(),
            Self::Commanded { gripper, .. } => gripper.plant(),
        }
    }

    /// The plant, mutably.
    pub fn plant_mut(&mut self) -> &mut Plant {
        match self {
            Self::GentleGrasp(t) => t.plant_mut(),
            Self::Commanded { gripper, .. } => gripper.plant_mut(),
        }
    }

    /// The task fields of the run report (none without a task).
    pub fn report(&self) -> Option<TaskReport> {
        match self {
            Self::GentleGrasp(t) => Some(t.report()),
            Self::Commanded {
                gripper,
                script_ends_run: true,
            } => gripper.script_report(),
            Self::Commanded { .. } => None,
        }
    }

    /// Each finger's phase, regulated force and target, N.
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        match self {
            Self::GentleGrasp(t) => t.fingers(),
            Self::Commanded { gripper, .. } => gripper.fingers(),
        }
    }

    /// Under `auto`, the force the grasp has found, N per finger (`None`: a fixed target,
    /// or no finger holds yet).
    pub fn settled_force_n(&self) -> Option<f64> {
        match self {
            Self::GentleGrasp(t) => t.settled_force_n(),
            Self::Commanded { gripper, .. } => gripper.settled_force_n(),
        }
    }

    /// The task for the page (the running or last script's; none before any).
    pub fn status(&self) -> Option<TaskStatus> {
        match self {
            Self::GentleGrasp(t) => {
                let stage = t.stage_label();
                Some(TaskStatus {
                    name: TASK_NAME.into(),
                    stage: stage.into(),
                    running: stage != "done",
                    outcome: (stage == "done").then(|| t.report().reason),
                })
            }
            Self::Commanded { gripper, .. } => {
                gripper.stage().map(|(name, stage, outcome)| TaskStatus {
                    name,
                    stage,
                    running: gripper.running_script().is_some(),
                    outcome,
                })
            }
        }
    }

    fn service_mut(&mut self) -> &mut GripperService {
        match self {
            Self::GentleGrasp(t) => t.service_mut(),
            Self::Commanded { gripper, .. } => gripper.service_mut(),
        }
    }

    /// Log the grasp-API service's commands and steps (for a recording).
    pub fn log_controller(&mut self) {
        self.service_mut().log_events();
    }

    /// The service's commands and steps since the last call (empty when not logging).
    pub fn take_controller_events(&mut self) -> Vec<ServiceEvent> {
        self.service_mut().take_events()
    }

    /// The grasp API's handle.
    pub fn handle(&self) -> GripperHandle {
        match self {
            Self::GentleGrasp(t) => t.handle(),
            Self::Commanded { gripper, .. } => gripper.handle(),
        }
    }
}

impl PilotControl for Pilot {
    fn running_task(&self) -> Option<&str> {
        match self {
            Self::GentleGrasp(_) => Some(TASK_NAME),
            Self::Commanded { gripper, .. } => gripper.running_script(),
        }
    }

    fn servo_states(&self) -> &[ServoState] {
        self.plant().states()
    }

    fn start_script(&mut self, script: TaskScript) -> Result<(), String> {
        match self {
            Self::GentleGrasp(_) => Err(TASK_NAME.to_string()),
            Self::Commanded { gripper, .. } => gripper.start_script(script),
        }
    }
}
