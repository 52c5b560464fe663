//! The grasp controller: one state machine per finger (open, approach, contact, squeeze,
//! hold, release, fault) regulating each finger's fused force to a target.
//!
//! [`GraspController::step`] is a pure function of the fused set, the servo states, the
//! time and the controller's own state; it does no I/O and sees no simulator type, so it is
//! deterministic and unit-tested here. Per finger:
//! - **Approach**: the goal is the closed position, reached at the requested speed through
//!   the servo's profile velocity, under a current cap of the free-motion current (what the
//!   return springs take, measured as the finger moves; raised by a margin whenever the cap
//!   holds the finger back) plus a small margin, so the first touch is soft. At the first
//!   contact on any of its sensors the finger slows (**contact**) and the cap stops rising.
//! - **Squeeze**: the goal leads the present position by the force error (0.25° per N, at
//!   most 15°), so the finger creeps toward the force target and stops there: in
//!   current-based position mode the servo holds a goal it has reached. The goal current is
//!   the hard force cap: the free-motion current (feed-forward) plus a PI term on the force
//!   error, never above the request's current limit; the integrator only runs while the
//!   output is not pinned in the error's direction (anti-windup). The force regulated is
//!   the median of the last three sets' fused force (a one-set outlier never moves a
//!   finger), averaged.
//! - **Hold**: after the force stays within ±5% of target for 0.5 s. The loop keeps running.
//!   Once every finger holds, the slip reflex ([`reflex`]) moves the target with the slip a
//!   marker gel shows, and a gross slip that `max_force_n` does not stop ends the grasp
//!   (`slipping`) with the fingers holding. Where no contact's slip is known, the contact
//!   area and centroid are taken as the reference; if on two sets in a row the area drops
//!   or the centroid moves (slip), the finger re-tightens: its target rises by 20% and it
//!   squeezes again. (Before every finger holds, the others move the object on purpose;
//!   that is not slip.)
//! - **No object**: a finger that reaches its closing goal, or stalls, without contact.
//! - **Slow set rates**: below 20 sets/s the approach speed and the current's proportional
//!   gain scale with the set period, the force is not median-filtered and is averaged over
//!   about 80 ms but at least two sets (`Tuning::reference_period_s`,
//!   `Tuning::force_span_s`), and a held finger moves only when its half-second average
//!   leaves the stable band (`Tuning::slow_hold_span_s`).
//! - **Stale**: a finger whose sensor is missing from the set holds where it is.
//! - **Release**: back to the open position at the approach current.

use serde::{Deserialize, Serialize};

use crate::actuator::{FingerGoal, ServoState};
use crate::fusion::FusedSet;

mod finger;
pub mod limits;
pub mod reflex;
pub mod settings;
pub mod stiffness;
pub mod target_force;
use finger::{FingerCtl, FingerInput, StepContext, Transition};
pub use limits::{GraspLimits, MAX_TIMEOUT_S};
pub use settings::GraspSettings;
pub use target_force::TargetForce;

/// Per-finger phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Open, not commanded.
    Open,
    /// Closing toward the object.
    Approach,
    /// First contact: slowing down.
    Contact,
    /// Regulating force toward the target.
    Squeeze,
    /// Force stable at target.
    Hold,
    /// Opening.
    Release,
    /// Stopped on a fault; holding.
    Fault,
}

/// Per-finger status, as gripper users know it (Robotiq-style object detection).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FingerStatus {
    /// Moving toward its goal.
    Moving,
    /// Stopped by contact while closing (holding an object).
    ContactClosing,
    /// At its requested position.
    AtGoal,
    /// Closed or stalled without touching anything.
    NoObject,
}

/// What the caller asks for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GraspRequest {
    /// Force per finger to regulate to, N.
    pub target_force_n: f64,
    /// Approach speed of the servo, deg/s.
    pub speed_deg_s: f64,
    /// Hard cap on every goal current, mA.
    pub current_limit_ma: f64,
    /// Fingers taking part (indices); the others stay where they are.
    pub fingers: Vec<usize>,
    /// Give up after this long, s.
    pub timeout_s: f64,
    /// The grasp finds its own force (`--target-force auto`): the fingers close to
    /// `[grasp] preload_n` and the slip reflex tightens them as far as the load needs, up
    /// to `max_force_n`; `target_force_n` is then not used. (Absent in older recordings:
    /// false.)
    #[serde(default)]
    pub auto_target: bool,
}

/// Controller constants (defaults documented in `docs/control.md`).
#[derive(Debug, Clone, PartialEq)]
pub struct Tuning {
    /// Largest current cap while approaching, mA.
    pub approach_current_ma: f64,
    /// While approaching, the cap is the free-motion current plus this margin, mA, so the
    /// first touch is soft.
    pub approach_margin_ma: f64,
    /// Speed share kept after first contact.
    pub contact_speed_share: f64,
    /// Share of `approach_margin_ma` kept after first contact: the contact is seen tens of
    /// ms late, and on a rigid object the whole margin alone pushes past a light target
    /// (30 mA is about 1.8 N at a middle pad), so the finger presses on with less until the
    /// squeeze regulates.
    pub contact_margin_share: f64,
    /// Largest goal lead beyond the present position while squeezing, degrees.
    pub squeeze_lead_deg: f64,
    /// Goal lead per N of force error while squeezing and holding, degrees per N: the
    /// position creeps toward the force target and stops there.
    pub squeeze_deg_per_n: f64,
    /// Proportional gain, mA per N of force error.
    pub kp_ma_per_n: f64,
    /// Integral gain, mA per N·s.
    pub ki_ma_per_n_s: f64,
    /// Smallest goal current while in contact, mA.
    pub min_current_ma: f64,
    /// Largest goal current the controller holds a squeeze at, whatever the request's
    /// limit, mA: a stalled XM430 held near its stall current overloads and cuts torque
    /// (in the motor model, 1.5 A for 1 s), so a squeeze never strains there.
    pub max_hold_current_ma: f64,
    /// "Stable": within this share of the target…
    pub stable_band: f64,
    /// …for this long, s.
    pub stable_s: f64,
    /// A finger that moves less than `stall_deg` in `stall_s` without contact has stalled.
    pub stall_s: f64,
    /// See `stall_s`, degrees.
    pub stall_deg: f64,
    /// Hold re-tightens when the area falls below this share of its value at hold…
    pub slip_area_share: f64,
    /// …or the centroid moves this far, mm.
    pub slip_shift_mm: f64,
    /// Target multiplier per re-tightening.
    pub retighten_factor: f64,
    /// Consecutive sets that must show slip before the finger re-tightens.
    pub slip_sets: u32,
    /// Weight of each new force reading in the regulated average (1 = no averaging); the
    /// readings are first the median of the last three sets, which rejects a one-set
    /// outlier.
    pub force_filter: f64,
    /// The averaging spans at most this long, s: when sets come further apart the weight
    /// per set rises (`1 − exp(−period / span)`, at most 0.5), and above
    /// `reference_period_s` the median of three is skipped (it would delay the force by a
    /// whole set).
    pub force_span_s: f64,
    /// The set period the gains are tuned for, s. At longer periods (slower set rates) the
    /// force the controller sees is older, so the approach speed and the current's
    /// proportional gain scale by `reference_period_s / period` to keep the loop stable.
    pub reference_period_s: f64,
    /// Below 20 sets/s a held finger is judged on its force averaged over this long, s, and
    /// left alone while that stays within the stable band: at slow set rates every
    /// correction is a large step on an old reading, and one reading can differ from the
    /// next by more than the band.
    pub slow_hold_span_s: f64,
    /// The `[grasp]` section: the slip reflex and the `auto` grasp.
    pub grasp: GraspSettings,
}

impl Default for Tuning {
    fn default() -> Self {
        Self {
            approach_current_ma: 400.0,
            approach_margin_ma: 30.0,
            contact_speed_share: 0.25,
            contact_margin_share: 0.5,
            squeeze_lead_deg: 15.0,
            squeeze_deg_per_n: 0.25,
            kp_ma_per_n: 15.0,
            ki_ma_per_n_s: 25.0,
            min_current_ma: 20.0,
            max_hold_current_ma: 1200.0,
            stable_band: 0.05,
            stable_s: 0.5,
            stall_s: 0.5,
            stall_deg: 0.5,
            slip_area_share: 0.75,
            slip_shift_mm: 0.5,
            retighten_factor: 1.2,
            slip_sets: 2,
            force_filter: 0.3,
            force_span_s: 0.08,
            reference_period_s: 0.05,
            slow_hold_span_s: 0.5,
            grasp: GraspSettings::default(),
        }
    }
}

/// Why a grasp ended. Serialises to the grasp API's `reason` strings: `stable`,
/// `force_limited`, `no_object`, `slipping`, `timeout after T s`, `preempted`, `released`,
/// `stopped`, `watchdog`, `estop`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GraspReason {
    /// Settled with at least two contacts at the target force.
    Stable,
    /// Settled with at least two contacts, held at what the current limit allows.
    ForceLimited,
    /// Settled without enough contact: nothing to grasp.
    NoObject,
    /// The object slid and the most force the settings allow (`grasp.max_force_n`) did not
    /// stop it; the fingers hold where they are. A grasp that had ended `stable` ends again
    /// with this when its hold gives way.
    Slipping,
    /// The request's own timeout passed first.
    Timeout {
        /// When, s since the grasp started.
        after_s: f64,
    },
    /// Another grasp replaced it.
    Preempted,
    /// A release ended it.
    Released,
    /// A stop ended it.
    Stopped,
    /// The run loop's watchdog stopped the motion (no gated set in time).
    Watchdog,
    /// An e-stop ended it.
    Estop,
}

impl GraspReason {
    /// The grasp holds the object (`stable` or `force_limited`).
    pub fn is_stable(self) -> bool {
        matches!(self, Self::Stable | Self::ForceLimited)
    }
}

impl std::fmt::Display for GraspReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Stable => f.write_str("stable"),
            Self::ForceLimited => f.write_str("force_limited"),
            Self::NoObject => f.write_str("no_object"),
            Self::Slipping => f.write_str("slipping"),
            Self::Timeout { after_s } => write!(f, "timeout after {after_s:.1} s"),
            Self::Preempted => f.write_str("preempted"),
            Self::Released => f.write_str("released"),
            Self::Stopped => f.write_str("stopped"),
            Self::Watchdog => f.write_str("watchdog"),
            Self::Estop => f.write_str("estop"),
        }
    }
}

/// Compares with the API's string (`reason == "stable"`).
impl PartialEq<&str> for GraspReason {
    fn eq(&self, other: &&str) -> bool {
        let text = self.to_string();
        text.as_str() == *other
    }
}

impl Serialize for GraspReason {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

/// How a grasp ended.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GraspOutcome {
    /// At least two contacts (fingers or palm) hold the object at a stable force.
    pub grasped: bool,
    /// Per finger.
    pub status: Vec<FingerStatus>,
    /// Total fused force at the end, N.
    pub final_force_n: f64,
    /// Why it ended.
    pub reason: GraspReason,
    /// The force per finger a grasp that found its own force (`auto_target`) settled on:
    /// the mean target of the fingers holding, N (`None` for a fixed target, or when
    /// nothing was grasped).
    pub settled_force_n: Option<f64>,
}

/// What one step commands.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlOutput {
    /// One goal per finger.
    pub goals: Vec<FingerGoal>,
    /// Set once the grasp has ended (stable, no object, or timed out).
    pub done: Option<GraspOutcome>,
}

/// Contact area (mm²) and centroid (sensor, x mm, y mm) that slip is measured against.
type SlipReference = (f64, Option<(usize, f64, f64)>);

/// The controller.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspController {
    request: GraspRequest,
    tuning: Tuning,
    close_deg: Vec<f64>,
    open_deg: Vec<f64>,
    fingers: Vec<FingerCtl>,
    started_s: Option<f64>,
    last_s: Option<f64>,
    /// When the last set arrived, s, and the running mean of the set period, s.
    last_set_s: Option<f64>,
    set_period_s: Option<f64>,
    /// Since when every active finger has held, s.
    settled_since_s: Option<f64>,
    done: Option<GraspOutcome>,
}

/// What the set period scales in one step.
struct RateScaling {
    /// Approach speed and proportional gain multiplier (1 at 20 sets/s and faster).
    gain_scale: f64,
    /// Weight of a new reading in the regulated average.
    weight: f64,
    /// Weight of a new reading in the slow (hold) average.
    slow_weight: f64,
    /// Take the median of the last three sets first.
    use_median: bool,
}

/// The regulated force always averages at least two sets (a reading that alternates from
/// set to set, as a slow hub's can, is mostly cancelled).
const MAX_FORCE_WEIGHT: f64 = 0.5;

/// An `auto` grasp whose fingers have all held this long has settled even while its reflex
/// still moves a target (a detector flickering between `none` and `incipient` on a contact
/// that holds keeps nudging it), s: the grasp's outcome comes, and the reflex goes on.
pub const AUTO_SETTLE_MAX_S: f64 = 3.0;

fn finite_or(v: f64, default: f64) -> f64 {
    if v.is_finite() { v } else { default }
}

impl Tuning {
    /// The cap while approaching or pressing on at first contact: the free-motion current
    /// plus `margin_ma`, within the approach's bounds and the request's `limit`, mA.
    fn approach_cap_ma(&self, feedforward_ma: f64, margin_ma: f64, limit: f64) -> f64 {
        (feedforward_ma + margin_ma)
            .clamp(self.min_current_ma, self.approach_current_ma)
            .min(limit)
    }
}

fn median3([a, b, c]: [f64; 3]) -> f64 {
    a.max(b).min(a.min(b).max(c))
}

impl GraspController {
    /// A controller for `request` on fingers that close toward `close_deg` and open to
    /// `open_deg` (servo degrees, one per finger).
    pub fn new(
        request: GraspRequest,
        tuning: Tuning,
        close_deg: Vec<f64>,
        open_deg: Vec<f64>,
    ) -> Self {
        // A grasp that finds its own force starts at the preload and may relax back to it;
        // one at a fixed target never relaxes below that.
        let target = if request.auto_target {
            tuning.grasp.preload_n
        } else {
            finite_or(request.target_force_n, 0.0).max(0.0)
        };
        let fingers = (0..close_deg.len())
            .map(|f| {
                let open = open_deg.get(f).copied().unwrap_or(0.0);
                FingerCtl::new(request.fingers.contains(&f), open, target)
            })
            .collect();
        Self {
            request,
            tuning,
            close_deg,
            open_deg,
            fingers,
            started_s: None,
            last_s: None,
            last_set_s: None,
            set_period_s: None,
            settled_since_s: None,
            done: None,
        }
    }

    /// Each finger's phase.
    pub fn phases(&self) -> Vec<Phase> {
        self.fingers.iter().map(|f| f.phase).collect()
    }

    /// Each finger's force as the controller regulates it (outlier-rejected, averaged), N.
    pub fn forces_n(&self) -> Vec<f64> {
        self.fingers.iter().map(|f| f.force_n).collect()
    }

    /// Each finger's status now.
    pub fn statuses(&self) -> Vec<FingerStatus> {
        self.fingers.iter().map(|f| f.status).collect()
    }

    /// Each finger's force target now (it rises when hold re-tightens), N.
    pub fn targets_n(&self) -> Vec<f64> {
        self.fingers.iter().map(|f| f.target_n).collect()
    }

    /// Each finger's phase, regulated force (N) and force target (N), for displays.
    pub fn finger_states(&self) -> Vec<(Phase, f64, f64)> {
        self.fingers
            .iter()
            .map(|f| (f.phase, f.force_n, f.target_n))
            .collect()
    }

    /// Whether the grip is still catching up with what the felt slip asks: a finger holding
    /// the object, its target short of `max_force_n`, whose reflex aims above its target,
    /// or whose force stands below its target, by more than the stable band (an `auto`
    /// lift waits for it; a grip at its most has nothing more to give).
    pub fn tightening(&self) -> bool {
        let band = 1.0 + self.tuning.stable_band;
        let most_n = self.tuning.grasp.max_force_n;
        self.fingers.iter().any(|f| {
            f.active
                && f.phase == Phase::Hold
                && f.status == FingerStatus::ContactClosing
                && f.target_n * band < most_n
                && (f.aim_n > band * f.target_n || f.force_n * band < f.target_n)
        })
    }

    /// The outcome, once the grasp has ended.
    pub fn outcome(&self) -> Option<&GraspOutcome> {
        self.done.as_ref()
    }

    /// The request's current limit, and never more than the largest holding current.
    fn limit(&self) -> f64 {
        finite_or(self.request.current_limit_ma, 0.0)
            .max(0.0)
            .min(self.tuning.max_hold_current_ma)
    }

    /// One control step at `t_s`, with the newest gated set (`None` if none arrived since the
    /// last step) and the servos' states.
    pub fn step(
        &mut self,
        t_s: f64,
        set: Option<&FusedSet>,
        servos: &[ServoState],
    ) -> ControlOutput {
        let first_step = self.started_s.is_none();
        let start = *self.started_s.get_or_insert(t_s);
        let dt = (t_s - self.last_s.unwrap_or(t_s)).clamp(0.0, 0.5);
        self.last_s = Some(t_s);
        let rate = self.track_set_rate(t_s, set.is_some());
        let active: Vec<bool> = self.fingers.iter().map(|c| c.active).collect();
        let k = StepContext {
            t_s,
            dt,
            limit_ma: self.limit(),
            speed_deg_s: finite_or(self.request.speed_deg_s, 0.0).max(0.0) * rate.gain_scale,
            rate,
            settled: self.settled(),
            auto_target: self.request.auto_target,
            grasp_slip: set.and_then(|s| s.worst_slip(&active)),
            held_slip: set.and_then(|s| s.held_slip(&active)),
            tuning: &self.tuning,
        };
        for (f, c) in self.fingers.iter_mut().enumerate() {
            let servo = servos.get(f);
            let now = FingerInput {
                present_deg: servo.map_or(c.goal_deg, |s| s.position_deg),
                close_deg: self.close_deg[f],
                open_deg: self.open_deg.get(f).copied().unwrap_or(0.0),
                servo,
            };
            let fused = set.and_then(|s| s.fingers.get(f)).copied();
            c.step(&k, &now, fused, first_step);
        }
        if !self.settled() {
            self.settled_since_s = None;
        } else if self.settled_since_s.is_none() {
            self.settled_since_s = Some(t_s);
        }
        let slipping = self.fingers.iter().any(|c| c.active && c.slipping);
        let ended_slipping = self
            .done
            .as_ref()
            .is_some_and(|d| d.reason == GraspReason::Slipping);
        if self.done.is_none() || (slipping && !ended_slipping) {
            self.done = self.check_done(t_s - start, set);
        }
        ControlOutput {
            goals: self.goals(),
            done: self.done.clone(),
        }
    }

    /// Track the set period and derive what it scales.
    fn track_set_rate(&mut self, t_s: f64, with_set: bool) -> RateScaling {
        let t = &self.tuning;
        if with_set {
            if let Some(prev) = self.last_set_s {
                let gap = (t_s - prev).clamp(0.0, 1.0);
                self.set_period_s = Some(match self.set_period_s {
                    Some(p) => p + (gap - p) * 0.2,
                    None => gap,
                });
            }
            self.last_set_s = Some(t_s);
        }
        let period = self.set_period_s.unwrap_or(0.0);
        let scale = if period > t.reference_period_s {
            t.reference_period_s / period
        } else {
            1.0
        };
        // 1 − exp(−period / span): the weight that spans `span` at this period.
        let spanning = |span: f64| {
            if span > 0.0 {
                1.0 - (-period / span).exp()
            } else {
                1.0
            }
        };
        RateScaling {
            gain_scale: scale,
            // No span: no averaging at all.
            weight: if t.force_span_s > 0.0 {
                t.force_filter
                    .max(spanning(t.force_span_s))
                    .min(MAX_FORCE_WEIGHT)
                    .clamp(0.0, 1.0)
            } else {
                1.0
            },
            slow_weight: spanning(t.slow_hold_span_s),
            use_median: period <= t.reference_period_s,
        }
    }

    /// A grasp that finds its own force has settled once every finger has held for
    /// `stable_s` with its reflex moving none of their targets by more than the stable band
    /// for as long, or for [`AUTO_SETTLE_MAX_S`] whatever the reflex does (a fixed target:
    /// at once).
    fn auto_settled(&self) -> bool {
        if !self.request.auto_target {
            return true;
        }
        let (Some(now), Some(since)) = (self.last_s, self.settled_since_s) else {
            return false;
        };
        let stable_s = self.tuning.stable_s;
        if now - since >= AUTO_SETTLE_MAX_S {
            return true;
        }
        now - since >= stable_s
            && self
                .fingers
                .iter()
                .filter(|c| c.active)
                .all(|c| c.moved_at_s.is_none_or(|t| now - t >= stable_s))
    }

    /// Whether the grasp finds its own force (`auto`).
    pub fn auto_target(&self) -> bool {
        self.request.auto_target
    }

    /// Under `auto`, the force the grasp has found: the mean target of the fingers holding
    /// the object, N (`None` for a fixed target, or with no finger holding).
    pub fn settled_force_n(&self) -> Option<f64> {
        let targets: Vec<f64> = self
            .fingers
            .iter()
            .filter(|c| c.active && c.status == FingerStatus::ContactClosing)
            .map(|c| c.target_n)
            .collect();
        (self.request.auto_target && !targets.is_empty())
            .then(|| targets.iter().sum::<f64>() / targets.len() as f64)
    }

    /// Every active finger holds (on the object, or having found none).
    fn settled(&self) -> bool {
        self.fingers.iter().filter(|c| c.active).all(|c| {
            c.phase == Phase::Hold
                && matches!(
                    c.status,
                    FingerStatus::ContactClosing | FingerStatus::NoObject
                )
        })
    }

    fn check_done(&self, elapsed_s: f64, set: Option<&FusedSet>) -> Option<GraspOutcome> {
        let active: Vec<&FingerCtl> = self.fingers.iter().filter(|c| c.active).collect();
        if active.iter().any(|c| c.slipping) {
            return Some(GraspOutcome {
                grasped: false,
                status: self.fingers.iter().map(|c| c.status).collect(),
                final_force_n: set.map_or(0.0, FusedSet::total_force_n),
                reason: GraspReason::Slipping,
                settled_force_n: None,
            });
        }
        let settled = self.settled() && self.auto_settled();
        let timed_out = elapsed_s >= finite_or(self.request.timeout_s, f64::INFINITY);
        if !settled && !timed_out {
            return None;
        }
        let holding = active
            .iter()
            .filter(|c| c.status == FingerStatus::ContactClosing)
            .count()
            + usize::from(set.and_then(|s| s.palm).is_some_and(|p| p.contact));
        let grasped = settled && holding >= 2;
        let limited = active.iter().any(|c| c.force_limited);
        let reason = if settled && grasped && limited {
            GraspReason::ForceLimited
        } else if settled && grasped {
            GraspReason::Stable
        } else if settled {
            GraspReason::NoObject
        } else {
            GraspReason::Timeout { after_s: elapsed_s }
        };
        let settled_force_n = self.settled_force_n().filter(|_| grasped);
        Some(GraspOutcome {
            grasped,
            status: self.fingers.iter().map(|c| c.status).collect(),
            final_force_n: set.map_or(0.0, FusedSet::total_force_n),
            reason,
            settled_force_n,
        })
    }

    /// The goals in force.
    pub fn goals(&self) -> Vec<FingerGoal> {
        self.fingers
            .iter()
            .map(|c| FingerGoal {
                position_deg: c.goal_deg,
                goal_current_ma: c.current_ma,
                profile_velocity_rpm: c.profile_rpm,
            })
            .collect()
    }

    /// Open every finger, also one a stop or an e-stop holds: opening is the operator's
    /// deliberate way out of a hold.
    pub fn release(&mut self) {
        for c in &mut self.fingers {
            if c.active {
                c.enter(Transition::Released);
            }
        }
    }

    /// Stop: every finger holds where it is, at its present current (`positions` from the
    /// last servo states).
    pub fn stop(&mut self, positions: &[f64]) {
        for (c, p) in self.fingers.iter_mut().zip(positions) {
            c.enter(Transition::Stopped { present_deg: *p });
        }
    }

    /// E-stop: hold where it is at the minimum current.
    pub fn estop(&mut self, positions: &[f64]) {
        let min = self.tuning.min_current_ma;
        self.stop(positions);
        for c in &mut self.fingers {
            c.current_ma = min;
        }
    }
}

#[cfg(test)]
pub(crate) mod tests;
