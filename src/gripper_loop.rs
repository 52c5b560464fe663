//! The gripper as the grasp API and task scripts share it. Every gated set goes through the
//! pipelines and then to whoever drives the fingers now:
//!
//! - a task script (from `--task NAME|FILE` or the dashboard's `POST /api/task`), which owns
//!   the gripper while it runs: the grasp API refuses grasps meanwhile (`Busy`), and any
//!   release, stop or e-stop that arrives interrupts the script and is carried out at once;
//! - otherwise the grasp API's service, so the dashboard's grasp, release, stop and e-stop
//!   act at once. Until a command arrives the fingers stay where they are (no goal is
//!   written); when a script ends they keep its last goals.

use gelgrip_controller::actuator::ServoBus;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::grasp::Phase;
use gelgrip_controller::gripper::{CommandKind, GripperHandle, GripperService};
use gelgrip_controller::task::TaskScript;
use gelgrip_sim::world::SharedWorld;

use crate::grasp_task::TaskReport;
use crate::script_task::ScriptRun;
use crate::task_io::TaskIo;

/// How a set or a command left a script that was running.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScriptEnd {
    /// It reached `done` or aborted on its own.
    Finished,
    /// A release or stop from the grasp API interrupted it.
    Interrupted,
    /// An e-stop from the grasp API interrupted it.
    Estop,
}

/// The gripper: its hardware, the grasp API's service and the script it may be running.
pub struct GripperLoop {
    io: TaskIo,
    gripper: GripperService,
    handle: GripperHandle,
    current_limit_ma: f64,
    script: Option<ScriptRun>,
    /// The script that ran last (kept for the report and the dashboard).
    last_script: Option<ScriptRun>,
    /// The watchdog fired and the fingers hold; cleared by the next gated set.
    pub watchdog_holding: bool,
}

impl GripperLoop {
    /// Open the pipelines and the servos (with the CSV log at `log`), and the grasp API's
    /// service.
    pub fn start(
        config: &AppConfig,
        bus: Box<dyn ServoBus>,
        world: Option<SharedWorld>,
        log: Option<&std::path::Path>,
    ) -> anyhow::Result<Self> {
        let io = TaskIo::open(config, bus, world, log)?;
        let (gripper, handle) =
            GripperService::for_hand(&io.layout, config.servos.current_limit_ma);
        Ok(Self {
            io,
            gripper,
            handle,
            current_limit_ma: config.servos.current_limit_ma,
            script: None,
            last_script: None,
            watchdog_holding: false,
        })
    }

    /// The grasp API's handle.
    /// The grasp-API service (to log its events for a recording).
    pub fn service_mut(&mut self) -> &mut GripperService {
        &mut self.gripper
    }

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
        self.gripper.forget();
        let run = ScriptRun::new(script, &self.io, self.current_limit_ma);
        tracing::info!(task = run.name(), "task script running");
        self.handle.set_busy(Some(run.name()));
        self.script = Some(run);
        Ok(())
    }

    /// Handle one gated set at host time `now_us`; reports how a script ended on it.
    pub fn on_set(&mut self, set: &FrameSet, now_us: u64) -> anyhow::Result<Option<ScriptEnd>> {
        if std::mem::take(&mut self.watchdog_holding) {
            tracing::info!("synchronized sets are back; the fingers held meanwhile");
        }
        if let Some(end) = self.check_interruption() {
            return Ok(Some(end));
        }
        if let Some(script) = self.script.as_mut() {
            if script.on_set(&mut self.io, set, now_us)? {
                self.end_script();
                return Ok(Some(ScriptEnd::Finished));
            }
            return Ok(None);
        }
        let sensed = self.io.drive(&mut self.gripper, set, now_us)?;
        self.io.remember(sensed.fused);
        Ok(None)
    }

    /// A command queued between sets is applied now: a stop or e-stop is written at once,
    /// and any command interrupts a running script.
    pub fn apply_urgent(&mut self) -> Option<ScriptEnd> {
        if let Some(end) = self.check_interruption() {
            return Some(end);
        }
        if self.script.is_none()
            && self.gripper.apply_commands(&self.io.positions())
            && let Some(goals) = self.gripper.goals()
        {
            self.io.write_now(&goals);
        }
        None
    }

    /// While a script runs: apply whatever commands arrived; any of them ends the script
    /// and the service carries it out from where the fingers are.
    fn check_interruption(&mut self) -> Option<ScriptEnd> {
        self.script.as_ref()?;
        let before = self.gripper.commands_applied();
        self.gripper.apply_commands(&self.io.positions());
        if self.gripper.commands_applied() == before {
            return None;
        }
        let estop = self.gripper.last_command() == Some(CommandKind::Estop);
        let command = match self.gripper.last_command() {
            Some(CommandKind::Grasp) => "grasp",
            Some(CommandKind::Release) => "release",
            Some(CommandKind::Stop) => "stop",
            Some(CommandKind::Estop) | None => "estop",
        };
        let reason = format!("interrupted: {command} through the grasp API");
        let reason = if estop { "estop".to_string() } else { reason };
        if let Some(script) = self.script.as_mut() {
            script.interrupt(&self.io, &reason);
            tracing::warn!(task = script.name(), reason, "task script interrupted");
        }
        if let Some(goals) = self.gripper.goals() {
            self.io.write_now(&goals);
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
        self.gripper.forget();
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
            script.hold_now(&mut self.io, reason);
            self.end_script();
            return;
        }
        let _ = self.handle.stop_on_watchdog();
        self.apply_urgent();
    }

    /// E-stop: every finger holds where it is at the minimum current.
    pub fn estop(&mut self) {
        if let Some(script) = self.script.as_mut() {
            script.estop(&mut self.io);
            self.end_script();
            return;
        }
        self.io.refresh_states();
        let _ = self.handle.estop();
        self.apply_urgent();
    }

    /// The end of the run: a running script is recorded as interrupted.
    pub fn interrupt(&mut self) {
        if let Some(script) = self.script.as_mut() {
            script.interrupt(&self.io, "the run ended first");
            self.end_script();
        }
    }

    /// Each finger's phase, force and target (before any command: open, 0, 0).
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        if let Some(script) = &self.script {
            return script.fingers();
        }
        let n = self.io.layout.fingers.len();
        self.gripper
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
            .map(|s| s.report(&self.io))
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
