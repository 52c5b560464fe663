//! The built-in `gentle-grasp` task: every gated set goes through the tactile pipelines,
//! is fused per finger, and steps the grasp controller through the grasp API
//! ([`crate::gripper`]: the task asks for the grasp, stop and e-stop through its handle, as
//! the dashboard does), whose goals are written to the servos at once. When the grasp is
//! stable (and after `hold_s`), the task tests the hold where there is a ground truth (the
//! object is let go and pulled with twice its weight, reached over 0.25 s as a lift
//! would, for 1 s; held = it slips less than 1 mm), then ends. Under `--target-force auto`
//! the grasp settles at the preload first; with a ground truth the task then lifts (the
//! object's weight comes on over 0.5 s, waiting while the slip reflex tightens:
//! [`crate::runtime::lift`]), the reflex tightens as far as the weight needs, and the force
//! it settles on under the weight is the grasp's `settled_force_n`.
//!
//! Safety: the controller acts only on gated sets; a finger with a missing sensor holds; a
//! watchdog stops all motion (hold at the present position) when no set arrives within
//! [`WATCHDOG_MS`](crate::runtime::plant::WATCHDOG_MS); an unrecovered servo fault ends the
//! run. Loop latency is wall-clock time from the gate handing over the set to the servo
//! write; capture-to-command adds the set's age at emission.

use crate::actuator::XM430_W350;
use crate::frame::FrameSet;
use crate::grasp::{
    GraspLimits, GraspOutcome, GraspReason, GraspRequest, GraspSettings, Phase, TargetForce,
};
use crate::gripper::{CommandKind, GripperError, GripperHandle, GripperService, PendingGrasp};
use crate::layout::HandLayout;
use crate::runtime::RuntimeError;
use crate::runtime::lift::{Lift, LiftStep};
use crate::runtime::outcome::EndReason;
use crate::runtime::plant::Plant;
use crate::runtime::ports::Sensing;
use crate::runtime::report::{DrivenSet, TaskStep};
use crate::runtime::task_report::TaskReport;

/// The built-in task's name (`run --task gentle-grasp`).
pub const TASK_NAME: &str = "gentle-grasp";

/// Length of the hold test once its pull is reached, s.
const HOLD_TEST_S: f64 = 1.0;
/// The hold test's pull rises to its full value over this long, s.
const HOLD_TEST_RISE_S: f64 = 0.25;
/// Under `auto`, the lift: by default the object's weight comes on over this long while
/// the grip keeps up, s ([`GraspOptions::lift_rise_s`]).
pub const LIFT_RISE_S: f64 = 0.5;
/// The longest a lift may take to bring the weight on (`--lift-rise-s`), s.
pub const MAX_LIFT_RISE_S: f64 = 60.0;
/// Weight multiple of the hold test.
const HOLD_TEST_FACTOR: f64 = 2.0;
/// "Held": slip during the hold test below this, mm.
const HELD_SLIP_MM: f64 = 1.0;

/// The task's options.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspOptions {
    /// Force per finger: N, or `auto` (the grasp finds its own).
    pub target_force: TargetForce,
    /// Approach speed, deg/s.
    pub speed_deg_s: f64,
    /// Give up after, s.
    pub timeout_s: f64,
    /// Once stable, keep holding this long before the hold test, s.
    pub hold_s: f64,
    /// Under `auto`, with a ground truth: the lift brings the object's weight on over
    /// this long while the grip keeps up, s (how fast the robot loads the grasp;
    /// [`LIFT_RISE_S`] by default; the weight waits while the reflex tightens).
    pub lift_rise_s: f64,
}

#[derive(Debug, Clone, Copy)]
enum Stage {
    Grasp,
    /// Under `auto`: the weight comes on as fast as the grip keeps up.
    Lift(Lift),
    Hold {
        until_s: f64,
    },
    HoldTest {
        since_s: f64,
        slip0_mm: f64,
    },
    Done,
}

/// The running task.
#[derive(Debug)]
pub struct GentleGrasp {
    /// The grasp API: the service this task steps, its handle, and the grasp it asked for.
    service: GripperService,
    handle: GripperHandle,
    pending: Option<PendingGrasp>,
    plant: Plant,
    stage: Stage,
    start_s: Option<f64>,
    outcome: Option<GraspOutcome>,
    peak_force_n: f64,
    hold_test_peak_force_n: Option<f64>,
    true_peak_force_n: Option<f64>,
    target_force: TargetForce,
    hold_s: f64,
    lift_rise_s: f64,
    time_to_stable_s: Option<f64>,
    hold_slip_mm: Option<f64>,
    /// The object's slip when the grasp became stable, mm: the hold test counts from
    /// here, so a slide (or a drop) during the lift or the hold counts too.
    slip_at_stable_mm: Option<f64>,
    /// Set when another client's command ended the task.
    interrupt_reason: Option<GraspReason>,
}

impl GentleGrasp {
    /// The grasp the task asks for on `layout`'s fingers, capped at `current_limit_ma`, its
    /// force kept as `grasp` says.
    pub fn request(
        layout: &HandLayout,
        current_limit_ma: f64,
        grasp: &GraspSettings,
        options: &GraspOptions,
    ) -> GraspRequest {
        GraspRequest {
            // Under `auto` the request's force is not used; the preload stands in for it in
            // the grasp limits' check.
            target_force_n: options.target_force.newtons().unwrap_or(grasp.preload_n),
            speed_deg_s: options.speed_deg_s,
            current_limit_ma,
            fingers: (0..layout.fingers.len()).collect(),
            timeout_s: options.timeout_s,
            auto_target: options.target_force.is_auto(),
        }
    }

    /// Check `options` against what `layout`'s fingers and servos can do at
    /// `current_limit_ma` ([`GraspLimits`]), before anything is opened: the same check
    /// [`GentleGrasp::start`] makes.
    pub fn check(
        layout: &HandLayout,
        current_limit_ma: f64,
        grasp: &GraspSettings,
        options: &GraspOptions,
    ) -> Result<(), GripperError> {
        GraspLimits::for_hand(layout, XM430_W350, current_limit_ma).check(&Self::request(
            layout,
            current_limit_ma,
            grasp,
            options,
        ))
    }

    /// Start the task on `plant`, whose currents stop at `current_limit_ma`: the grasp is
    /// asked for at once (a bad request, or one beyond the hand's [`GraspLimits`], is
    /// refused here).
    pub fn start(
        plant: Plant,
        current_limit_ma: f64,
        grasp: GraspSettings,
        options: &GraspOptions,
    ) -> Result<Self, GripperError> {
        let layout = &plant.layout;
        let request = Self::request(layout, current_limit_ma, &grasp, options);
        let (service, handle) = GripperService::for_hand(layout, current_limit_ma, grasp);
        let pending = handle.start_grasp(request)?;
        // Other clients (the dashboard) may stop or e-stop this grasp, never start another.
        handle.set_busy(Some(TASK_NAME));
        Ok(Self {
            service,
            handle,
            pending: Some(pending),
            plant,
            stage: Stage::Grasp,
            start_s: None,
            outcome: None,
            peak_force_n: 0.0,
            hold_test_peak_force_n: None,
            true_peak_force_n: None,
            target_force: options.target_force,
            hold_s: options.hold_s,
            lift_rise_s: options.lift_rise_s,
            time_to_stable_s: None,
            hold_slip_mm: None,
            slip_at_stable_mm: None,
            interrupt_reason: None,
        })
    }

    fn slip_mm(&self) -> Option<f64> {
        self.plant.truth()?.slip_mm()
    }

    /// Handle one gated set at host time `now_us`, sensed through `sensing`: what it did,
    /// with an end reason when the task ends.
    pub fn on_set(&mut self, sensing: &mut dyn Sensing, set: &FrameSet, now_us: u64) -> DrivenSet {
        let t_s = now_us as f64 / 1e6;
        let start = *self.start_s.get_or_insert(t_s);
        let sensed = match self.plant.drive(sensing, &mut self.service, set, now_us) {
            Ok(sensed) => sensed,
            Err(e) => return DrivenSet::without_step(Err(e)),
        };
        if let Some(end) = self.interrupted() {
            return DrivenSet {
                sensed: Some(sensed),
                step: None,
                controller_events: Vec::new(),
                end: Ok(Some(end)),
            };
        }
        let truth = self.plant.true_forces_n();
        let regulated = self
            .service
            .controller()
            .map_or(0.0, |c| c.forces_n().into_iter().fold(0.0, f64::max));
        match self.stage {
            Stage::Grasp | Stage::Lift(_) | Stage::Hold { .. } => {
                self.peak_force_n = self.peak_force_n.max(regulated);
                if let Some(peak) = self.plant.true_finger_peak_n(&truth) {
                    self.true_peak_force_n = Some(self.true_peak_force_n.unwrap_or(0.0).max(peak));
                }
            }
            Stage::HoldTest { .. } => {
                self.hold_test_peak_force_n =
                    Some(self.hold_test_peak_force_n.unwrap_or(0.0).max(regulated));
            }
            Stage::Done => {}
        }
        let (phases, goals) = self
            .service
            .controller()
            .map(|c| (c.phases(), c.goals()))
            .unwrap_or_default();
        let step = Some(TaskStep {
            trigger_seq: set.trigger_seq,
            t_s: t_s - start,
            stage: self.stage_label().to_string(),
            truth_n: truth,
            phases,
            goals,
        });
        DrivenSet {
            end: self.advance(t_s, start),
            sensed: Some(sensed),
            step,
            controller_events: Vec::new(),
        }
    }

    /// Move the task on after the set at `t_s` (the task began at `start`): the grasp's
    /// outcome, the hold, the hold test; returns an end reason when the task ends.
    fn advance(&mut self, t_s: f64, start: f64) -> Result<Option<EndReason>, RuntimeError> {
        match self.stage {
            Stage::Grasp => {
                let ended = self.pending.as_mut().and_then(PendingGrasp::try_outcome);
                if let Some(outcome) = ended {
                    self.pending = None;
                    let outcome = outcome.map_err(RuntimeError::Grasp)?;
                    let stable = outcome.reason.is_stable();
                    if stable {
                        self.time_to_stable_s = Some(t_s - start);
                        self.slip_at_stable_mm = self.slip_mm();
                    }
                    self.outcome = Some(outcome);
                    if stable && self.target_force.is_auto() && self.begin_lift(t_s) {
                        return Ok(None);
                    }
                    return Ok(self.hold_after_stable(stable, t_s));
                }
            }
            Stage::Lift(lift) => {
                if self.slipping() {
                    self.stage = Stage::Done;
                    return Ok(Some(EndReason::Done));
                }
                return Ok(self.advance_lift(t_s, lift));
            }
            Stage::Hold { until_s } => {
                if t_s >= until_s {
                    return Ok(self.begin_hold_test(true, t_s));
                }
            }
            Stage::HoldTest { since_s, slip0_mm } => {
                self.slipping();
                if t_s - since_s >= HOLD_TEST_RISE_S + HOLD_TEST_S {
                    self.hold_slip_mm = self.slip_mm().map(|s| (s - slip0_mm).abs());
                    self.stage = Stage::Done;
                    return Ok(Some(EndReason::Done));
                }
            }
            Stage::Done => return Ok(Some(EndReason::Done)),
        }
        Ok(None)
    }

    /// After a stable grasp: hold for `hold_s`, then the hold test (at once without a
    /// hold, or after a grasp that did not hold); returns an end reason when the task ends.
    fn hold_after_stable(&mut self, stable: bool, t_s: f64) -> Option<EndReason> {
        if stable && self.hold_s > 0.0 {
            self.stage = Stage::Hold {
                until_s: t_s + self.hold_s,
            };
            None
        } else {
            self.begin_hold_test(stable, t_s)
        }
    }

    /// Under `auto`, with a ground truth: let the object go, its weight to come on over
    /// the options' `lift_rise_s` as the grip keeps up ([`Lift`]; false without a ground
    /// truth: the grasp's outcome stands).
    fn begin_lift(&mut self, t_s: f64) -> bool {
        let Some(truth) = self.plant.truth_mut() else {
            return false;
        };
        truth.pull_object(0.0, 0.0);
        self.stage = Stage::Lift(Lift::begin(t_s, self.lift_rise_s));
        true
    }

    /// The lift at `t_s`: the weight's share comes on while the grip keeps up; once the
    /// grip has settled under the whole weight, the outcome takes that force and the task
    /// holds.
    fn advance_lift(&mut self, t_s: f64, mut lift: Lift) -> Option<EndReason> {
        let controller = self.service.controller();
        let tightening = controller.is_some_and(|c| c.tightening());
        let settled_n = controller.and_then(|c| c.settled_force_n());
        match lift.step(t_s, tightening, settled_n) {
            LiftStep::Load { share, over_s } => {
                if let Some(truth) = self.plant.truth_mut() {
                    truth.pull_object(share, over_s);
                }
                self.stage = Stage::Lift(lift);
                None
            }
            // No finger holds any more: the outcome stands and the hold test tells.
            LiftStep::Ungripped => self.hold_after_stable(true, t_s),
            LiftStep::Settled { force_n } => {
                let slip_mm = self.slip_mm();
                tracing::debug!(
                    force_n,
                    waited_s = lift.waited_s(),
                    ?slip_mm,
                    "auto lift settled"
                );
                if let Some(outcome) = self.outcome.as_mut() {
                    outcome.settled_force_n = Some(force_n);
                }
                self.hold_after_stable(true, t_s)
            }
        }
    }

    /// Whether the controller has ended the grasp `slipping` since its outcome (the reflex
    /// could not stop a slide within `max_force_n`; the fingers hold): the task's outcome
    /// takes that reason.
    fn slipping(&mut self) -> bool {
        let ended = self
            .service
            .controller()
            .and_then(|c| c.outcome())
            .filter(|o| o.reason == GraspReason::Slipping)
            .cloned();
        match ended {
            Some(o) => {
                self.outcome = Some(o);
                true
            }
            None => false,
        }
    }

    /// A release, stop or e-stop from another client (its own grasp is the first command)
    /// ends the task: `estop` for an e-stop, else `done`, with the command as the reason.
    fn interrupted(&mut self) -> Option<EndReason> {
        if self.service.commands_applied() <= 1 || matches!(self.stage, Stage::Done) {
            return None;
        }
        let command = self.service.last_command()?;
        let (reason, end) = match command {
            CommandKind::Estop => (GraspReason::Estop, EndReason::Estop),
            CommandKind::Stop => (GraspReason::Stopped, EndReason::Done),
            CommandKind::Release => (GraspReason::Released, EndReason::Done),
            CommandKind::Grasp => return None,
        };
        tracing::warn!(%reason, "gentle grasp interrupted through the grasp API");
        if let Some(outcome) = self.outcome.as_mut() {
            outcome.reason = reason;
            outcome.grasped = false;
        }
        self.interrupt_reason = Some(reason);
        self.pending = None;
        self.stage = Stage::Done;
        Some(end)
    }

    /// The grasp-API service (to log its events for a recording).
    pub fn service_mut(&mut self) -> &mut GripperService {
        &mut self.service
    }

    /// The grasp API's handle (the dashboard's commands reach this task through it).
    pub fn handle(&self) -> GripperHandle {
        self.handle.clone()
    }

    /// After a stable grasp, with a ground truth: let the object go and pull it (the hold
    /// test); otherwise the task ends (returns the end reason).
    fn begin_hold_test(&mut self, stable: bool, t_s: f64) -> Option<EndReason> {
        let slip0 = self.slip_at_stable_mm.or_else(|| self.slip_mm());
        match (stable, self.plant.truth_mut(), slip0) {
            (true, Some(truth), Some(slip0)) => {
                truth.pull_object(HOLD_TEST_FACTOR, HOLD_TEST_RISE_S);
                self.stage = Stage::HoldTest {
                    since_s: t_s,
                    slip0_mm: slip0,
                };
                None
            }
            _ => {
                self.stage = Stage::Done;
                Some(EndReason::Done)
            }
        }
    }

    /// Check the watchdog at host time `now_us`; returns a fault description when it fires
    /// (all motion stopped: every finger holds where it is).
    pub fn watchdog(&mut self, now_us: u64) -> Option<String> {
        let silent_ms = self.plant.watchdog_silence_ms(now_us)?;
        let _ = self.handle.stop_on_watchdog();
        self.hold_now();
        Some(format!(
            "watchdog: no synchronized set for {silent_ms} ms; fingers hold"
        ))
    }

    /// E-stop: every finger holds where it is at the minimum current; torque stays on.
    pub fn estop(&mut self) {
        self.plant.refresh_states();
        let _ = self.handle.estop();
        self.hold_now();
    }

    /// Apply the queued stop or e-stop and write its hold goals at once.
    fn hold_now(&mut self) {
        self.service.apply_commands(&self.plant.positions());
        if let Some(goals) = self.service.goals() {
            self.plant.write_now(&goals);
        }
    }

    /// Each finger's phase, regulated force and target, N.
    pub fn fingers(&self) -> Vec<(Phase, f64, f64)> {
        self.service
            .controller()
            .map_or_else(Vec::new, |c| c.finger_states())
    }

    /// Under `auto`, the force the grasp settled on (the lift's, once it is measured), or
    /// the one it is finding; `None` for a fixed target.
    pub fn settled_force_n(&self) -> Option<f64> {
        self.outcome
            .as_ref()
            .and_then(|o| o.settled_force_n)
            .or_else(|| self.service.controller().and_then(|c| c.settled_force_n()))
    }

    /// The stage now (`grasp`, `lift`, `hold`, `hold_test`, `done`).
    pub fn stage_label(&self) -> &'static str {
        match self.stage {
            Stage::Grasp => "grasp",
            Stage::Lift(_) => "lift",
            Stage::Hold { .. } => "hold",
            Stage::HoldTest { .. } => "hold_test",
            Stage::Done => "done",
        }
    }

    /// The plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The plant, mutably.
    pub fn plant_mut(&mut self) -> &mut Plant {
        &mut self.plant
    }

    /// The task fields (the latencies are the runtime's: see
    /// [`TaskReport::with_latencies`]).
    pub fn report(&self) -> TaskReport {
        let outcome = self.outcome.clone();
        let held = self.hold_slip_mm.is_none_or(|s| s < HELD_SLIP_MM);
        TaskReport {
            task: TASK_NAME.into(),
            grasped: outcome.as_ref().is_some_and(|o| o.grasped) && held,
            peak_force_n: self.peak_force_n,
            hold_test_peak_force_n: self.hold_test_peak_force_n,
            true_peak_force_n: self.true_peak_force_n,
            target_force_n: self.target_force.newtons(),
            settled_force_n: outcome.as_ref().and_then(|o| o.settled_force_n),
            time_to_stable_s: self.time_to_stable_s,
            loop_latency_ms_p50: None,
            loop_latency_ms_p99: None,
            capture_to_command_ms_p50: None,
            capture_to_command_ms_p99: None,
            loop_own_ms_p99: None,
            pipeline_ms_p99: None,
            final_force_n: outcome.as_ref().map(|o| o.final_force_n),
            reason: match (&outcome, self.interrupt_reason) {
                (Some(o), _) => o.reason.to_string(),
                (None, Some(r)) => r.to_string(),
                (None, None) => "not finished".into(),
            },
            finger_status: outcome.map(|o| o.status).unwrap_or_default(),
            hold_slip_mm: self.hold_slip_mm,
            stages: None,
        }
    }
}
