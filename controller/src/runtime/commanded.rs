//! The gripper as the grasp API and task scripts share it. Every gated set goes through the
//! pipelines and then to whoever drives the fingers now:
//!
//! - a task script (from `--task NAME|FILE` or the dashboard's `POST /api/task`), which owns
//!   the gripper while it runs: the grasp API refuses grasps meanwhile (`Busy`), and any
//!   release, stop or e-stop that arrives interrupts the script and is carried out at once;
//! - otherwise the grasp API's service, so the dashboard's grasp, release, stop and e-stop
//!   act at once. Until a command arrives the fingers stay where they are (no goal is
//!   written); when a script ends they keep its last goals.

use crate::frame::FrameSet;
use crate::grasp::{GraspSettings, Phase};
use crate::gripper::{CommandKind, GripperHandle, GripperService};
use crate::runtime::RuntimeError;
use crate::runtime::outcome::ScriptEnd;
use crate::runtime::plant::Plant;
use crate::runtime::ports::Sensing;
use crate::runtime::report::{Sensed, TaskStep};
use crate::runtime::script_run::ScriptRun;
use crate::runtime::task_report::TaskReport;
use crate::task::TaskScript;

/// What the commanded gripper did with one set.
#[derive(Debug)]
pub struct CommandedPass {
    /// The set sensed and answered (`None` when a command interrupted the script first).
    pub sensed: Option<Sensed>,
    /// A row of the task log, while a script runs.
    pub step: Option<TaskStep>,
    /// How the script ended, if it did.
    pub end: Option<ScriptEnd>,
}

impl CommandedPass {
    fn without_set(end: ScriptEnd) -> Self {
        Self {
            sensed: None,
            step: None,
            end: Some(end),
        }
    }
}

/// The gripper commanded through the grasp API and task scripts: its plant, the grasp
/// API's service and the script it may be running.
#[derive(Debug)]
pub struct CommandedGripper {
    plant: Plant,
    service: GripperService,
    handle: GripperHandle,
    current_limit_ma: f64,
    grasp: GraspSettings,
    script: Option<ScriptRun>,
    /// The script that ran last (kept for the report and the dashboard).
    last_script: Option<ScriptRun>,
    /// The watchdog fired and the fingers hold; cleared by the next gated set.
    pub watchdog_holding: bool,
}

impl CommandedGripper {
    /// The gripper on `plant`, whose currents stop at `current_limit_ma`, its grasps and
    /// scripts keeping their force as `grasp` says.
    pub fn new(plant: Plant, current_limit_ma: f64, grasp: GraspSettings) -> Self {
        let (service, handle) = GripperService::for_hand(&plant.layout, current_limit_ma, grasp);
        Self {
            plant,
            service,
            handle,
            current_limit_ma,
            grasp,
            script: None,
            last_script: None,
            watchdog_holding: false,
        }
    }

    /// The grasp-API service (to log its events for a recording).
    pub fn service_mut(&mut self) -> &mut GripperService {
        &mut self.service
    }

    /// The grasp API's handle.
    pub fn handle(&self) -> GripperHandle {
        self.handle.clone()
    }

    /// The script running now, if any.
    pub fn running_script(&self) -> Option<&str> {
        self.script.as_ref().map(ScriptRun::name)
    }

    /// Start `script`; refused (with the running script's name) while another runs. A grasp
    /// in progress is preempted: the script takes the fingers from where they are.
    pub fn start_script(&mut self, script: TaskScript) -> Result<(), String> {
        if let Some(name) = self.running_script() {
            return Err(name.to_string());
        }
        // Commands queued before the start belong to the service, not to the script.
        self.apply_urgent();
        self.service.forget();
        let run = ScriptRun::new(script, &self.plant, self.current_limit_ma, self.grasp);
        tracing::info!(task = run.name(), "task script running");
        self.handle.set_busy(Some(run.name()));
        self.script = Some(run);
        Ok(())
    }

    /// Handle one gated set at host time `now_us`, sensed through `sensing`: a running
    /// script's row of the task log, and how a script ended on it.
    pub fn on_set(
        &mut self,
        sensing: &mut dyn Sensing,
        set: &FrameSet,
        now_us: u64,
    ) -> Result<CommandedPass, RuntimeError> {
        if std::mem::take(&mut self.watchdog_holding) {
            tracing::info!("synchronized sets are back; the fingers held meanwhile");
        }
        if let Some(end) = self.check_interruption() {
            return Ok(CommandedPass::without_set(end));
        }
        if let Some(script) = self.script.as_mut() {
            let (sensed, step, ended) = script.on_set(&mut self.plant, sensing, set, now_us)?;
            if ended {
                self.end_script();
                return Ok(CommandedPass {
                    sensed: Some(sensed),
                    step: Some(step),
                    end: Some(ScriptEnd::Finished),
                });
            }
            return Ok(CommandedPass {
                sensed: Some(sensed),
                step: Some(step),
                end: None,
            });
        }
        let sensed = self.plant.drive(sensing, &mut self.service, set, now_us)?;
        Ok(CommandedPass {
            sensed: Some(sensed),
            step: None,
            end: None,
        })
    }

    /// A command queued between sets is applied now: a stop or e-stop is written at once,
    /// and any command interrupts a running script.
    pub fn apply_urgent(&mut self) -> Option<ScriptEnd> {
        if let Some(end) = self.check_interruption() {
            return Some(end);
        }
        if self.script.is_none()
            && self.service.apply_commands(&self.plant.positions())
            && let Some(goals) = self.service.goals()
        {
            self.plant.write_now(&goals);
        }
        None
    }

    /// While a script runs: apply whatever commands arrived; any of them ends the script
    /// and the service carries it out from where the fingers are.
    fn check_interruption(&mut self) -> Option<ScriptEnd> {
        self.script.as_ref()?;
        let before = self.service.commands_applied();
        self.service.apply_commands(&self.plant.positions());
        if self.service.commands_applied() == before {
            return None;
        }
        let estop = self.service.last_command() == Some(CommandKind::Estop);
        let command = match self.service.last_command() {
            Some(CommandKind::Grasp) => "grasp",
            Some(CommandKind::Release) => "release",
            Some(CommandKind::Stop) => "stop",
            Some(CommandKind::Estop) | None => "estop",
        };
        let reason = format!("interrupted: {command} through the grasp API");
        let reason = if estop { "estop".to_string() } else { reason };
        if let Some(script) = self.script.as_mut() {
            script.interrupt(&self.plant, &reason);
            tracing::warn!(task = script.name(), reason, "task script interrupted");
        }
        if let Some(goals) = self.service.goals() {
            self.plant.write_now(&goals);
        }
        self.end_script_keeping_service();
        Some(if estop {
            ScriptEnd::Estop
        } else {
            ScriptEnd::Interrupted
        })
    }

    /// The script ended on its own: the fingers keep its last goals.
    fn end_script(&mut self) {
        self.service.forget();
        self.end_script_keeping_service();
    }

    fn end_script_keeping_service(&mut self) {
        self.last_script = self.script.take();
        self.handle.set_busy(None);
    }

    /// The watchdog fired: stop all motion, every finger holds where it is (a running
    /// script ends; a waiting grasp call resolves with the reason `watchdog`).
    pub fn hold(&mut self, reason: &str) {
        if let Some(script) = self.script.as_mut() {
            script.hold_now(&mut self.plant, reason);
            self.end_script();
            return;
        }
        let _ = self.handle.stop_on_watchdog();
        self.apply_urgent();
    }

    /// E-stop: every finger holds where it is at the minimum current.
    pub fn estop(&mut self) {
        if let Some(script) = self.script.as_mut() {
            script.estop(&mut self.plant);
            self.end_script();
            return;
        }
        self.plant.refresh_states();
        let _ = self.handle.estop();
        self.apply_urgent();
    }

    /// The end of the run: a running script is recorded as interrupted.
    pub fn interrupt(&mut self) {
        if let Some(script) = self.script.as_mut() {
            script.interrupt(&self.plant, "the run ended first");
            self.end_script();
        }
    }

    /// Under `auto`, the force the running script's or the API's grasp has found, N per
    /// finger.
    pub fn settled_force_n(&self) -> Option<f64> {
        if let Some(script) = &self.script {
            return script.settled_force_n();
        }
        self.service.controller().and_then(|c| c.settled_force_n())
    }

    /// Each finger's phase, force and target (before any command: open, 0, 0).
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        if let Some(script) = &self.script {
            return script.fingers();
        }
        let n = self.plant.layout.fingers.len();
        self.service
            .controller()
            .map_or_else(|| vec![(Phase::Open, 0.0, 0.0); n], |c| c.finger_states())
    }

    /// The running (or last) script's name, stage and outcome (`None` while it runs).
    pub fn stage(&self) -> Option<(String, String, Option<String>)> {
        self.script.as_ref().or(self.last_script.as_ref()).map(|s| {
            let (name, stage) = s.stage();
            (name, stage, s.outcome())
        })
    }

    /// The running (or last) script's task fields.
    pub fn script_report(&self) -> Option<TaskReport> {
        self.script
            .as_ref()
            .or(self.last_script.as_ref())
            .map(ScriptRun::report)
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, mutably.
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }
}
