//! The grasp API: a cloneable [`GripperHandle`] through which any task (the CLI's gentle
//! grasp, the dashboard) asks for `grasp`, `release`, `stop` and `estop`, and the
//! [`GripperService`] that the run loop owns and steps once per gated set.
//!
//! The handle never touches the servos: it queues commands, and the run loop applies them
//! at its next step (or at once for `stop` and `estop`, see
//! [`GripperService::apply_commands`]). A grasp call resolves with the controller's outcome
//! (`grasped`, per-finger status, `final_force_n`, `reason`) when the grasp ends: stable,
//! force-limited, no object, or its own timeout. No call can block forever: a grasp that is
//! replaced by another, released, stopped (by a call or the run loop's watchdog) or
//! e-stopped resolves at once with that reason,
//! and when the run loop ends every waiting call gets [`GripperError::Stopped`].
//!
//! The queue holds [`COMMAND_QUEUE`] commands (the loop drains it on every pass, so it fills
//! only while the loop is stuck): a grasp or release beyond it is refused with
//! [`GripperError::QueueFull`]; a stop or e-stop is never refused: it is kept aside (an
//! e-stop over a stop) and applied after the queue at the next drain.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};

use serde::{Deserialize, Serialize};
use thiserror::Error;
use tokio::sync::{mpsc, oneshot};

use crate::actuator::XM430_W350;
use crate::actuator::{FingerGoal, ServoState};
use crate::fusion::FusedSet;
use crate::grasp::{
    FingerStatus, GraspController, GraspLimits, GraspOutcome, GraspReason, GraspRequest,
    GraspSettings, TargetForce, Tuning,
};

/// Why a grasp-API call failed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum GripperError {
    /// The run loop that drives the gripper has ended (or never started).
    #[error("the gripper's run loop has stopped: no command can be carried out")]
    Stopped,
    /// A task owns the gripper; a grasp would fight it. Stop the task first (release, stop
    /// and e-stop are always accepted, and interrupt it).
    #[error("task `{task}` is driving the gripper: stop it before a new grasp")]
    Busy {
        /// The task's name.
        task: String,
    },
    /// The command queue is full: the run loop has not taken a command for a while.
    #[error(
        "the gripper's command queue is full ({capacity} commands): the run loop is not keeping up; try again"
    )]
    QueueFull {
        /// Its capacity.
        capacity: usize,
    },
    /// The request cannot be carried out as given.
    #[error("invalid grasp request: {field} = {value} ({expected})")]
    InvalidRequest {
        /// The offending field.
        field: &'static str,
        /// Its value, as given.
        value: String,
        /// What is allowed.
        expected: String,
    },
}

/// The kinds of grasp-API command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandKind {
    /// `grasp`.
    Grasp,
    /// `release`.
    Release,
    /// `stop`.
    Stop,
    /// `estop`.
    Estop,
}

/// Commands the queue holds; it fills only while the run loop is stuck.
pub const COMMAND_QUEUE: usize = 256;

/// A stop or e-stop kept aside while the queue was full (0: none): the most urgent wins.
const URGENT_NONE: u8 = 0;
const URGENT_STOP: u8 = 1;
const URGENT_WATCHDOG: u8 = 2;
const URGENT_ESTOP: u8 = 3;

enum Command {
    Grasp(GraspRequest, oneshot::Sender<GraspOutcome>),
    Release,
    /// Hold where they are; a waiting grasp resolves with the reason (`stopped`, or
    /// `watchdog` when the run loop's watchdog stopped the motion).
    Stop(GraspReason),
    Estop,
}

/// A command as the service applied it: what a recording keeps, and a replay applies again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum AppliedCommand {
    /// A grasp started.
    Grasp {
        /// As requested.
        request: GraspRequest,
    },
    /// Release.
    Release,
    /// Stop, holding at these positions, degrees.
    Stop {
        /// The servos' positions then.
        positions_deg: Vec<f64>,
    },
    /// E-stop, holding at these positions, degrees.
    Estop {
        /// The servos' positions then.
        positions_deg: Vec<f64>,
    },
}

/// What the service did, in order (while logging): its inputs and its decisions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum ServiceEvent {
    /// A command applied.
    Applied {
        /// The command.
        command: AppliedCommand,
    },
    /// A control step: its inputs (time, whether a fused set came, the servo states) and
    /// its decision (the goals, `None` before any command).
    Step {
        /// Time, s.
        t_s: f64,
        /// A fused set was given.
        with_set: bool,
        /// The servo states given.
        servos: Vec<ServoState>,
        /// The goals returned.
        goals: Option<Vec<FingerGoal>>,
    },
}

/// A grasp in progress: its outcome arrives when it ends.
#[derive(Debug)]
pub struct PendingGrasp {
    reply: oneshot::Receiver<GraspOutcome>,
}

impl PendingGrasp {
    /// The outcome if the grasp has ended, without waiting.
    pub fn try_outcome(&mut self) -> Option<Result<GraspOutcome, GripperError>> {
        match self.reply.try_recv() {
            Ok(outcome) => Some(Ok(outcome)),
            Err(oneshot::error::TryRecvError::Empty) => None,
            Err(oneshot::error::TryRecvError::Closed) => Some(Err(GripperError::Stopped)),
        }
    }

    /// Wait for the outcome.
    pub async fn outcome(self) -> Result<GraspOutcome, GripperError> {
        self.reply.await.map_err(|_| GripperError::Stopped)
    }
}

/// The caller's side of the grasp API; clone it freely.
#[derive(Debug, Clone)]
pub struct GripperHandle {
    tx: mpsc::Sender<Command>,
    /// A stop or e-stop that found the queue full (`URGENT_*`).
    urgent: Arc<AtomicU8>,
    fingers: usize,
    /// What the hand can do: a request's force, speed and timeout are refused outside it
    /// (`None`: only their signs are checked, for a service made without a layout).
    limits: Option<Arc<GraspLimits>>,
    /// The task that owns the gripper, if any (grasps are refused meanwhile).
    busy: Arc<Mutex<Option<String>>>,
    /// `[grasp] preload_n`: where an `auto` grasp closes to, N.
    preload_n: f64,
}

impl std::fmt::Debug for Command {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Command::Grasp(..) => "Grasp",
            Command::Release => "Release",
            Command::Stop(_) => "Stop",
            Command::Estop => "Estop",
        })
    }
}

fn invalid(field: &'static str, value: impl ToString, expected: &str) -> GripperError {
    GripperError::InvalidRequest {
        field,
        value: value.to_string(),
        expected: expected.to_string(),
    }
}

impl GripperHandle {
    /// Check `request` against this gripper: its fingers and current cap, then its force,
    /// speed and timeout against the hand's [`GraspLimits`] (when it has them).
    pub fn validate(&self, request: &GraspRequest) -> Result<(), GripperError> {
        if !(request.current_limit_ma.is_finite() && request.current_limit_ma >= 0.0) {
            return Err(invalid(
                "current_limit_ma",
                request.current_limit_ma,
                "a finite current of at least 0 mA",
            ));
        }
        if request.fingers.is_empty() || request.fingers.iter().any(|f| *f >= self.fingers) {
            return Err(invalid(
                "fingers",
                format!("{:?}", request.fingers),
                &format!("finger indices below {}, at least one", self.fingers),
            ));
        }
        if let Some(limits) = &self.limits {
            return limits.check(request);
        }
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(request.target_force_n) {
            return Err(invalid(
                "target_force_n",
                request.target_force_n,
                "a finite force above 0 N",
            ));
        }
        if !positive(request.speed_deg_s) {
            return Err(invalid(
                "speed_deg_s",
                request.speed_deg_s,
                "a finite speed above 0 deg/s",
            ));
        }
        if !positive(request.timeout_s) {
            return Err(invalid(
                "timeout_s",
                request.timeout_s,
                "a finite time above 0 s",
            ));
        }
        Ok(())
    }

    /// What the hand can do, when the service was made for one
    /// ([`GripperService::for_hand`]).
    pub fn limits(&self) -> Option<&GraspLimits> {
        self.limits.as_deref()
    }

    /// A request's force and whether the grasp finds its own, for `target`: under `auto`
    /// the request carries `[grasp] preload_n` (where the fingers close to, and what the
    /// grasp limits check).
    pub fn target(&self, target: TargetForce) -> (f64, bool) {
        (target.newtons().unwrap_or(self.preload_n), target.is_auto())
    }

    /// The task that owns the gripper now, if any.
    pub fn busy(&self) -> Option<String> {
        self.busy.lock().map_or(None, |b| b.clone())
    }

    /// Mark the gripper as owned by `task` (`None`: free). While it is owned,
    /// [`start_grasp`](Self::start_grasp) is refused with [`GripperError::Busy`]; release,
    /// stop and e-stop still go through, and the owner treats them as an interruption.
    pub fn set_busy(&self, task: Option<&str>) {
        if let Ok(mut b) = self.busy.lock() {
            *b = task.map(str::to_string);
        }
    }

    /// Start a grasp; a grasp already running is replaced (its caller gets `preempted`).
    /// Refused while a task owns the gripper.
    pub fn start_grasp(&self, request: GraspRequest) -> Result<PendingGrasp, GripperError> {
        if let Some(task) = self.busy() {
            return Err(GripperError::Busy { task });
        }
        self.validate(&request)?;
        let (reply, rx) = oneshot::channel();
        self.send(Command::Grasp(request, reply))?;
        Ok(PendingGrasp { reply: rx })
    }

    /// Grasp and wait for the outcome.
    pub async fn grasp(&self, request: GraspRequest) -> Result<GraspOutcome, GripperError> {
        self.start_grasp(request)?.outcome().await
    }

    /// Open every finger.
    pub fn release(&self) -> Result<(), GripperError> {
        self.send(Command::Release)
    }

    /// Every finger holds where it is.
    pub fn stop(&self) -> Result<(), GripperError> {
        self.send(Command::Stop(GraspReason::Stopped))
    }

    /// The run loop's watchdog fired (no gated set in time): every finger holds where it
    /// is, as for [`GripperHandle::stop`], and a waiting grasp resolves with the reason
    /// `watchdog`.
    pub fn stop_on_watchdog(&self) -> Result<(), GripperError> {
        self.send(Command::Stop(GraspReason::Watchdog))
    }

    /// Every finger holds where it is at the minimum current.
    pub fn estop(&self) -> Result<(), GripperError> {
        self.send(Command::Estop)
    }

    fn send(&self, command: Command) -> Result<(), GripperError> {
        use mpsc::error::TrySendError;
        let command = match self.tx.try_send(command) {
            Ok(()) => return Ok(()),
            Err(TrySendError::Closed(_)) => return Err(GripperError::Stopped),
            Err(TrySendError::Full(command)) => command,
        };
        let urgent = match command {
            Command::Stop(GraspReason::Watchdog) => URGENT_WATCHDOG,
            Command::Stop(_) => URGENT_STOP,
            Command::Estop => URGENT_ESTOP,
            Command::Grasp(..) | Command::Release => {
                return Err(GripperError::QueueFull {
                    capacity: COMMAND_QUEUE,
                });
            }
        };
        tracing::warn!("grasp-API queue full: a stop or e-stop kept aside for the next pass");
        self.urgent.fetch_max(urgent, Ordering::SeqCst);
        Ok(())
    }
}

/// The run loop's side of the grasp API: the controller, driven by the commands queued
/// through the handles.
#[derive(Debug)]
pub struct GripperService {
    rx: mpsc::Receiver<Command>,
    urgent: Arc<AtomicU8>,
    tuning: Tuning,
    close_deg: Vec<f64>,
    open_deg: Vec<f64>,
    current_limit_ma: f64,
    ctl: Option<GraspController>,
    waiting: Option<oneshot::Sender<GraspOutcome>>,
    commands_applied: u64,
    last_command: Option<CommandKind>,
    /// The events since they were last taken, while logging.
    log: Option<Vec<ServiceEvent>>,
}

impl GripperService {
    /// A service for fingers that close toward `close_deg` and open to `open_deg`, whose
    /// release, stop and e-stop (without a grasp) use `current_limit_ma`; and its handle.
    pub fn new(
        tuning: Tuning,
        close_deg: Vec<f64>,
        open_deg: Vec<f64>,
        current_limit_ma: f64,
    ) -> (Self, GripperHandle) {
        let (tx, rx) = mpsc::channel(COMMAND_QUEUE);
        let urgent = Arc::new(AtomicU8::new(URGENT_NONE));
        let handle = GripperHandle {
            tx,
            urgent: urgent.clone(),
            fingers: close_deg.len(),
            limits: None,
            busy: Arc::new(Mutex::new(None)),
            preload_n: tuning.grasp.preload_n,
        };
        let service = Self {
            rx,
            urgent,
            tuning,
            close_deg,
            open_deg,
            current_limit_ma,
            ctl: None,
            waiting: None,
            commands_applied: 0,
            last_command: None,
            log: None,
        };
        (service, handle)
    }

    /// The service for `layout`'s fingers (closing toward each finger's servo range, open
    /// at 0°) with the default tuning, the `[grasp]` section's `grasp` and
    /// `current_limit_ma` as the cap; its handle refuses
    /// requests beyond what these fingers and their XM430-W350 servos can do at that cap
    /// ([`GraspLimits`]).
    pub fn for_hand(
        layout: &crate::layout::HandLayout,
        current_limit_ma: f64,
        grasp: GraspSettings,
    ) -> (Self, GripperHandle) {
        let close: Vec<f64> = layout.fingers.iter().map(|f| f.servo_range_deg).collect();
        let n = close.len();
        let tuning = Tuning {
            grasp,
            ..Tuning::default()
        };
        let (service, mut handle) = Self::new(tuning, close, vec![0.0; n], current_limit_ma);
        handle.limits = Some(Arc::new(GraspLimits::for_hand(
            layout,
            XM430_W350,
            current_limit_ma,
        )));
        (service, handle)
    }

    /// Keep a log of commands applied and steps taken (for a recording).
    pub fn log_events(&mut self) {
        self.log.get_or_insert_with(Vec::new);
    }

    /// The events logged since the last call (empty when not logging).
    pub fn take_events(&mut self) -> Vec<ServiceEvent> {
        self.log.as_mut().map(std::mem::take).unwrap_or_default()
    }

    /// Apply a recorded command again (a replay): as if it had come through a handle.
    pub fn replay(&mut self, command: &AppliedCommand) -> bool {
        let (command, positions) = match command {
            AppliedCommand::Grasp { request } => {
                let (reply, _) = oneshot::channel();
                (Command::Grasp(request.clone(), reply), Vec::new())
            }
            AppliedCommand::Release => (Command::Release, Vec::new()),
            AppliedCommand::Stop { positions_deg } => {
                (Command::Stop(GraspReason::Stopped), positions_deg.clone())
            }
            AppliedCommand::Estop { positions_deg } => (Command::Estop, positions_deg.clone()),
        };
        self.apply(command, &positions)
    }

    /// The controller of the current (or last) grasp.
    pub fn controller(&self) -> Option<&GraspController> {
        self.ctl.as_ref()
    }

    /// The goals in force (`None` before any command).
    pub fn goals(&self) -> Option<Vec<FingerGoal>> {
        self.ctl.as_ref().map(GraspController::goals)
    }

    /// A controller for commands that come without a grasp: every finger, no force.
    fn idle_controller(&self) -> GraspController {
        GraspController::new(
            GraspRequest {
                target_force_n: 0.0,
                speed_deg_s: 0.0,
                current_limit_ma: self.current_limit_ma,
                fingers: (0..self.close_deg.len()).collect(),
                timeout_s: f64::INFINITY,
                auto_target: false,
            },
            self.tuning.clone(),
            self.close_deg.clone(),
            self.open_deg.clone(),
        )
    }

    /// Resolve the waiting grasp call, if any, with `reason`.
    fn end_waiting(&mut self, reason: GraspReason) {
        if let Some(reply) = self.waiting.take() {
            let n = self.close_deg.len();
            let outcome = GraspOutcome {
                grasped: false,
                status: self.ctl.as_ref().map_or_else(
                    || vec![FingerStatus::Moving; n],
                    |c| {
                        c.outcome()
                            .map_or_else(|| c.statuses(), |o| o.status.clone())
                    },
                ),
                final_force_n: self.ctl.as_ref().map_or(0.0, |c| c.forces_n().iter().sum()),
                reason,
                settled_force_n: None,
            };
            let _ = reply.send(outcome);
        }
    }

    /// Apply every queued command; `positions` are the servos' last positions (stop and
    /// e-stop hold there). Returns true when the goals changed in a way that must reach
    /// the servos at once (stop, e-stop), without waiting for the next set.
    pub fn apply_commands(&mut self, positions: &[f64]) -> bool {
        let mut urgent = false;
        while let Ok(command) = self.rx.try_recv() {
            urgent |= self.apply(command, positions);
        }
        let aside = match self.urgent.swap(URGENT_NONE, Ordering::SeqCst) {
            URGENT_ESTOP => Some(Command::Estop),
            URGENT_WATCHDOG => Some(Command::Stop(GraspReason::Watchdog)),
            URGENT_STOP => Some(Command::Stop(GraspReason::Stopped)),
            _ => None,
        };
        if let Some(command) = aside {
            urgent |= self.apply(command, positions);
        }
        urgent
    }

    /// Apply one command; true when it must reach the servos at once.
    fn apply(&mut self, command: Command, positions: &[f64]) -> bool {
        self.commands_applied += 1;
        self.last_command = Some(match &command {
            Command::Grasp(..) => CommandKind::Grasp,
            Command::Release => CommandKind::Release,
            Command::Stop(_) => CommandKind::Stop,
            Command::Estop => CommandKind::Estop,
        });
        if let Some(log) = self.log.as_mut() {
            let command = match &command {
                Command::Grasp(request, _) => AppliedCommand::Grasp {
                    request: request.clone(),
                },
                Command::Release => AppliedCommand::Release,
                Command::Stop(_) => AppliedCommand::Stop {
                    positions_deg: positions.to_vec(),
                },
                Command::Estop => AppliedCommand::Estop {
                    positions_deg: positions.to_vec(),
                },
            };
            log.push(ServiceEvent::Applied { command });
        }
        match command {
            Command::Grasp(request, reply) => {
                self.end_waiting(GraspReason::Preempted);
                self.ctl = Some(GraspController::new(
                    request,
                    self.tuning.clone(),
                    self.close_deg.clone(),
                    self.open_deg.clone(),
                ));
                self.waiting = Some(reply);
                false
            }
            Command::Release => {
                self.end_waiting(GraspReason::Released);
                let idle = self.idle_controller();
                self.ctl.get_or_insert(idle).release();
                false
            }
            Command::Stop(reason) => {
                self.end_waiting(reason);
                let idle = self.idle_controller();
                self.ctl.get_or_insert(idle).stop(positions);
                true
            }
            Command::Estop => {
                self.end_waiting(GraspReason::Estop);
                let idle = self.idle_controller();
                self.ctl.get_or_insert(idle).estop(positions);
                true
            }
        }
    }

    /// Commands applied so far (a task that owns the gripper watches it: any command
    /// interrupts the task, and this service takes over).
    pub fn commands_applied(&self) -> u64 {
        self.commands_applied
    }

    /// The kind of the last command applied.
    pub fn last_command(&self) -> Option<CommandKind> {
        self.last_command
    }

    /// Forget the controller: no goals until the next command (the servos keep what they
    /// were last told, e.g. by a task that just ended).
    pub fn forget(&mut self) {
        self.end_waiting(GraspReason::Preempted);
        self.ctl = None;
    }

    /// One control step with the newest gated set; returns the goals to write (`None`
    /// before any command). A grasp that ends here resolves its caller.
    pub fn step(
        &mut self,
        t_s: f64,
        set: Option<&FusedSet>,
        servos: &[ServoState],
    ) -> Option<Vec<FingerGoal>> {
        let goals = self.ctl.as_mut().map(|ctl| {
            let out = ctl.step(t_s, set, servos);
            (out.done, out.goals)
        });
        let goals = goals.map(|(done, goals)| {
            if let Some(outcome) = done
                && let Some(reply) = self.waiting.take()
            {
                let _ = reply.send(outcome);
            }
            goals
        });
        if let Some(log) = self.log.as_mut() {
            log.push(ServiceEvent::Step {
                t_s,
                with_set: set.is_some(),
                servos: servos.to_vec(),
                goals: goals.clone(),
            });
        }
        goals
    }
}

#[cfg(test)]
mod tests;
