//! One finger's state machine: what each phase does on a set ([`FingerCtl::step`] and one
//! function per phase), and every phase change through one place ([`FingerCtl::enter`],
//! with the [`Transition`] that says what the change resets).

use super::reflex::{self, GIVE_UP_S};
use super::stiffness::StiffnessTrack;
use super::{FingerStatus, Phase, RateScaling, SlipReference, Tuning, finite_or, median3};
use crate::actuator::ServoState;
use crate::fusion::{FusedContact, SensorSlip, SlipState};

/// Sets in a row without contact after which a held finger that felt slip has lost its
/// object (three, as a squeeze that feels nothing is given).
const LOST_SETS: u32 = 3;

/// Under `auto`, a squeeze that felt no slip for this long and then feels it goes to the
/// reflex, s.
const QUIET_BEFORE_LOAD_S: f64 = 0.5;

/// What one control step knows beside the finger, the same for every finger.
pub(super) struct StepContext<'a> {
    /// The step's time, s.
    pub(super) t_s: f64,
    /// Time since the last step, s (at most 0.5).
    pub(super) dt: f64,
    /// The current limit in force, mA.
    pub(super) limit_ma: f64,
    /// What the set period scales.
    pub(super) rate: RateScaling,
    /// The approach speed, scaled by the set period, deg/s.
    pub(super) speed_deg_s: f64,
    /// Every active finger held before this step.
    pub(super) settled: bool,
    /// The grasp finds its own force (`auto`): its squeeze's target is the preload.
    pub(super) auto_target: bool,
    /// The slip of the contact slipping most over the grasp's fingers and the palm (`None`:
    /// no contact's slip is known; the reflex then watches contact motion).
    pub(super) grasp_slip: Option<SensorSlip>,
    /// The slip the grasp holds by: that of the contact slipping most among those bearing
    /// their share of the force (`None` as above); the reflex's.
    pub(super) held_slip: Option<SensorSlip>,
    /// The controller's constants.
    pub(super) tuning: &'a Tuning,
}

/// Where one finger's servo stands this step, and where its travel ends.
pub(super) struct FingerInput<'a> {
    /// The servo's present position (the last goal when unread), degrees.
    pub(super) present_deg: f64,
    /// The closed position, degrees.
    pub(super) close_deg: f64,
    /// The open position, degrees.
    pub(super) open_deg: f64,
    /// The servo's state, when read.
    pub(super) servo: Option<&'a ServoState>,
}

/// A phase change, and what entering the new phase resets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Transition {
    /// Open → approach, on the grasp's first step.
    Start {
        /// Where the finger stands, degrees.
        present_deg: f64,
    },
    /// Approach → contact: the first touch, the cap lowered to `cap_ma` at most.
    Touch {
        /// The step's time, s.
        t_s: f64,
        /// The approach cap with the contact's margin, mA.
        cap_ma: f64,
    },
    /// Contact → approach: the contact went away before the squeeze.
    LostTouch,
    /// Contact → squeeze.
    Squeeze,
    /// Approach or contact → hold: closed or stalled without touching anything.
    NoObject {
        /// Where the finger stands, degrees.
        present_deg: f64,
    },
    /// Squeeze → approach: what was squeezed was never felt (a noisy frame).
    Unfelt {
        /// The approach cap, mA.
        cap_ma: f64,
    },
    /// Squeeze → hold at the current limit, a little below the force reached.
    ForceLimited {
        /// The force held, N.
        target_n: f64,
    },
    /// Squeeze → hold: the force stayed in the stable band.
    Stable,
    /// Hold → squeeze: slip; the target rises by `factor`.
    Slip {
        /// The target's multiplier.
        factor: f64,
    },
    /// Hold → hold where it is: a gross slip that the most force allowed did not stop.
    Slipping {
        /// Where the finger stands, degrees.
        present_deg: f64,
    },
    /// Release → open: the finger reached its open position.
    Opened,
    /// Any phase → release (an active finger).
    Released,
    /// Any phase → fault: a stop or an e-stop; the finger holds at `present_deg`.
    Stopped {
        /// Where the finger stands, degrees.
        present_deg: f64,
    },
}

/// One finger's controller state.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct FingerCtl {
    pub(super) phase: Phase,
    pub(super) active: bool,
    pub(super) goal_deg: f64,
    pub(super) current_ma: f64,
    integral_ma: f64,
    feedforward_ma: f64,
    pub(super) profile_rpm: f64,
    contact_since_s: Option<f64>,
    /// Sets in a row that showed the contact since it began.
    contact_sets: u32,
    /// The largest regulated force since the approach began, N.
    peak_n: f64,
    /// The force averaged over `Tuning::slow_hold_span_s`, N.
    slow_force_n: f64,
    pub(super) target_n: f64,
    /// The least the reflex relaxes to: the request's target, or `preload_n` for a grasp
    /// that finds its own force, N.
    floor_n: f64,
    /// When the reflex last moved the target by more than the stable band from where it
    /// had stood (`moved_from_n`), s.
    pub(super) moved_at_s: Option<f64>,
    moved_from_n: f64,
    /// When the reflex last moved the target, s.
    reflex_at_s: Option<f64>,
    /// What the reflex last aimed the target at, N (the target while it has not acted).
    pub(super) aim_n: f64,
    /// The least force that holds, as the reflex tracks it.
    least: reflex::LeastTrack,
    /// The force at which the last slide stopped (a floor of the reflex's aim).
    slide_stop: reflex::SlideStop,
    /// The contact's stiffness, from the finger's motion since the touch (the force
    /// loop's step).
    stiffness: StiffnessTrack,
    /// Since when the grasp has slid with the target at its most, s.
    gross_since_s: Option<f64>,
    /// Since when the squeeze has felt no slip (known `none`), s.
    quiet_since_s: Option<f64>,
    /// The squeeze felt no slip for `QUIET_BEFORE_LOAD_S`: a load felt after that came
    /// after the touch.
    quiet_seen: bool,
    /// When the grasp last felt slip (incipient or gross) while this finger held, s.
    slip_felt_at_s: Option<f64>,
    /// Sets in a row this held finger has felt no contact.
    lost_sets: u32,
    /// The grasp slid and the most force allowed did not stop it: the finger holds.
    pub(super) slipping: bool,
    stable_since_s: Option<f64>,
    stall_ref: Option<(f64, f64)>,
    /// Contact area and centroid that slip is measured against (armed once the whole
    /// grasp holds, since until then the other fingers move the object on purpose).
    slip_ref: Option<SlipReference>,
    slip_seen: u32,
    /// Since when (s), and at what force (N), the goal current has been pinned at the
    /// limit while squeezing.
    cap_ref: Option<(f64, f64)>,
    /// The current limit allowed no more force: the finger holds what it reached.
    pub(super) force_limited: bool,
    pub(super) status: FingerStatus,
    /// The last three fused forces, newest last, N.
    recent_n: [f64; 3],
    pub(super) force_n: f64,
}

impl FingerCtl {
    /// An open finger at `goal_deg`, taking part when `active`, regulating to `target_n`,
    /// which the reflex relaxes to at the least.
    pub(super) fn new(active: bool, goal_deg: f64, target_n: f64) -> Self {
        Self {
            phase: Phase::Open,
            active,
            goal_deg,
            current_ma: 0.0,
            integral_ma: 0.0,
            feedforward_ma: 0.0,
            profile_rpm: 0.0,
            contact_since_s: None,
            contact_sets: 0,
            peak_n: 0.0,
            slow_force_n: 0.0,
            target_n,
            floor_n: target_n,
            moved_at_s: None,
            moved_from_n: target_n,
            reflex_at_s: None,
            aim_n: target_n,
            least: reflex::LeastTrack::default(),
            slide_stop: reflex::SlideStop::default(),
            stiffness: StiffnessTrack::default(),
            gross_since_s: None,
            quiet_since_s: None,
            quiet_seen: false,
            slip_felt_at_s: None,
            lost_sets: 0,
            slipping: false,
            stable_since_s: None,
            stall_ref: None,
            slip_ref: None,
            slip_seen: 0,
            cap_ref: None,
            force_limited: false,
            status: FingerStatus::AtGoal,
            recent_n: [0.0; 3],
            force_n: 0.0,
        }
    }

    /// Change phase: the only place a finger's phase changes.
    pub(super) fn enter(&mut self, transition: Transition) {
        match transition {
            Transition::Start { present_deg } => {
                self.phase = Phase::Approach;
                self.goal_deg = present_deg;
                self.status = FingerStatus::Moving;
            }
            Transition::Touch { t_s, cap_ma } => {
                self.phase = Phase::Contact;
                self.contact_since_s = Some(t_s);
                self.contact_sets = 0;
                self.current_ma = cap_ma.min(self.current_ma);
                self.quiet_since_s = None;
                self.quiet_seen = false;
                self.stiffness = StiffnessTrack::default();
            }
            Transition::LostTouch => {
                self.phase = Phase::Approach;
                self.contact_since_s = None;
            }
            Transition::Squeeze => {
                self.phase = Phase::Squeeze;
                self.integral_ma = 0.0;
                self.feedforward_ma = self.feedforward_ma.min(self.current_ma);
            }
            Transition::NoObject { present_deg } => {
                self.phase = Phase::Hold;
                self.status = FingerStatus::NoObject;
                self.goal_deg = present_deg;
            }
            Transition::Unfelt { cap_ma } => {
                self.phase = Phase::Approach;
                self.contact_since_s = None;
                self.integral_ma = 0.0;
                self.current_ma = cap_ma;
            }
            Transition::ForceLimited { target_n } => {
                self.target_n = target_n;
                self.force_limited = true;
                self.cap_ref = None;
                self.hold_on_contact();
            }
            Transition::Stable => self.hold_on_contact(),
            Transition::Slip { factor } => {
                self.target_n *= factor;
                self.phase = Phase::Squeeze;
                self.stable_since_s = None;
                self.slip_ref = None;
                self.slip_seen = 0;
            }
            Transition::Slipping { present_deg } => {
                self.phase = Phase::Hold;
                self.slipping = true;
                self.goal_deg = present_deg;
            }
            Transition::Opened => {
                self.phase = Phase::Open;
                self.status = FingerStatus::AtGoal;
            }
            Transition::Released => {
                self.phase = Phase::Release;
                self.status = FingerStatus::Moving;
            }
            Transition::Stopped { present_deg } => {
                self.goal_deg = present_deg;
                self.phase = Phase::Fault;
            }
        }
    }

    /// Hold on the object; slip is measured from the next settled set.
    fn hold_on_contact(&mut self) {
        self.phase = Phase::Hold;
        self.status = FingerStatus::ContactClosing;
        self.slip_ref = None;
        self.slip_seen = 0;
        self.reflex_at_s = None;
        self.aim_n = self.target_n;
        self.least = reflex::LeastTrack::default();
        self.slide_stop = reflex::SlideStop::default();
        self.gross_since_s = None;
        self.slip_felt_at_s = None;
        self.lost_sets = 0;
    }

    /// One step of this finger on its fused contact (`None`: no new set, the goals stay).
    pub(super) fn step(
        &mut self,
        k: &StepContext<'_>,
        now: &FingerInput<'_>,
        fused: Option<FusedContact>,
        first_step: bool,
    ) {
        if !self.active || matches!(self.phase, Phase::Fault) {
            return;
        }
        // Only the grasp's first step starts the approach: a finger that a release opened
        // stays open.
        if self.phase == Phase::Open && first_step {
            self.enter(Transition::Start {
                present_deg: now.present_deg,
            });
        }
        let Some(fused) = fused else {
            return; // no new set: keep the last goals
        };
        if fused.stale {
            self.goal_deg = now.present_deg; // hold, never guess
            return;
        }
        self.filter_force(fused.force_n, &k.rate);
        if matches!(self.phase, Phase::Contact | Phase::Squeeze | Phase::Hold) {
            self.stiffness.observe(now.present_deg, fused.force_n);
        }
        match self.phase {
            Phase::Approach | Phase::Contact => self.approach(k, now, &fused),
            Phase::Squeeze if !fused.contact && self.peak_n < 0.05 * self.target_n => {
                self.squeeze_unfelt(k);
            }
            Phase::Hold if self.slipping => self.goal_deg = now.present_deg,
            Phase::Squeeze | Phase::Hold => self.regulate(k, now, &fused),
            Phase::Release => self.release(k, now),
            Phase::Open | Phase::Fault => {}
        }
    }

    /// Regulate on a short average of the median of the last three sets: a one-set
    /// outlier of the pipeline never moves the finger.
    fn filter_force(&mut self, force_n: f64, rate: &RateScaling) {
        self.recent_n = [self.recent_n[1], self.recent_n[2], finite_or(force_n, 0.0)];
        let median = if rate.use_median {
            median3(self.recent_n)
        } else {
            self.recent_n[2]
        };
        self.force_n = if self.force_n == 0.0 {
            median
        } else {
            self.force_n + (median - self.force_n) * rate.weight
        };
        let force_n = self.force_n;
        self.slow_force_n = if self.slow_force_n == 0.0 {
            force_n
        } else {
            self.slow_force_n + (force_n - self.slow_force_n) * rate.slow_weight
        };
        if self.phase == Phase::Approach {
            self.peak_n = 0.0;
        } else {
            self.peak_n = self.peak_n.max(force_n);
        }
    }

    /// Approach and contact: close at the requested speed under the learnt cap; slow at
    /// the first touch; squeeze once the touch is sure, or hold having found nothing.
    fn approach(&mut self, k: &StepContext<'_>, now: &FingerInput<'_>, fused: &FusedContact) {
        let t = k.tuning;
        let measured = now
            .servo
            .map_or(0.0, |s| finite_or(s.current_ma.abs(), 0.0));
        // A contact that goes away before the squeeze was not one: approach on.
        if fused.contact && self.phase == Phase::Approach {
            let margin = t.approach_margin_ma * t.contact_margin_share;
            let cap_ma = t.approach_cap_ma(self.feedforward_ma, margin, k.limit_ma);
            self.enter(Transition::Touch { t_s: k.t_s, cap_ma });
        } else if !fused.contact && self.phase == Phase::Contact {
            self.enter(Transition::LostTouch);
        }
        if self.phase == Phase::Contact {
            self.contact_sets += 1;
        }
        if self.phase == Phase::Approach {
            self.learn_free_motion(k, now, measured);
        } else {
            self.profile_rpm = k.speed_deg_s * t.contact_speed_share / 6.0;
        }
        self.goal_deg = now.close_deg;
        let in_contact_s = self.contact_since_s.map_or(0.0, |s0| k.t_s - s0);
        // Squeeze once the force is a third of the way there, or once the contact has
        // lasted 0.3 s and three sets (at slow set rates 0.3 s is one or two sets, too few
        // to tell a touch from a noisy frame).
        if self.phase == Phase::Contact
            && (self.force_n >= 0.3 * self.target_n
                || (in_contact_s >= 0.3 && self.contact_sets >= 3))
        {
            self.enter(Transition::Squeeze);
        } else if !fused.contact {
            self.check_no_object(k, now);
        }
    }

    /// Learn what the return springs take: track the free-motion current, and when the
    /// cap holds the finger back, raise it by the margin.
    fn learn_free_motion(&mut self, k: &StepContext<'_>, now: &FingerInput<'_>, measured: f64) {
        let t = k.tuning;
        let crawling = now
            .servo
            .is_none_or(|s| finite_or(s.velocity_rpm, 0.0).abs() * 6.0 < 0.3 * k.speed_deg_s);
        let pinned = measured >= self.current_ma - 2.0 && crawling;
        self.feedforward_ma = if pinned {
            self.current_ma
        } else {
            self.feedforward_ma + (measured - self.feedforward_ma) * 0.5
        };
        self.current_ma = t.approach_cap_ma(self.feedforward_ma, t.approach_margin_ma, k.limit_ma);
        self.profile_rpm = k.speed_deg_s / 6.0;
    }

    /// Without contact: a finger that stalls at the approach's cap, or reaches its
    /// closing goal, has found no object.
    fn check_no_object(&mut self, k: &StepContext<'_>, now: &FingerInput<'_>) {
        let t = k.tuning;
        let present = now.present_deg;
        let (ref_s, ref_deg) = *self.stall_ref.get_or_insert((k.t_s, present));
        if (present - ref_deg).abs() > t.stall_deg {
            self.stall_ref = Some((k.t_s, present));
        } else if (k.t_s - ref_s >= t.stall_s
            && self.current_ma >= t.approach_current_ma.min(k.limit_ma))
            || present >= now.close_deg - 1.0
        {
            self.enter(Transition::NoObject {
                present_deg: present,
            });
        }
    }

    /// Squeezing what was never felt (the contact was a noisy frame): three sets in a row
    /// without contact and the finger approaches again, its current back to the
    /// approach's, instead of winding up on air.
    fn squeeze_unfelt(&mut self, k: &StepContext<'_>) {
        let t = k.tuning;
        self.contact_sets = self.contact_sets.min(3).saturating_sub(1);
        if self.contact_sets == 0 {
            let cap_ma = t.approach_cap_ma(self.feedforward_ma, t.approach_margin_ma, k.limit_ma);
            self.enter(Transition::Unfelt { cap_ma });
        }
    }

    /// Squeeze and hold: regulate the force to the target, hold once it is stable or the
    /// current limit allows no more, and re-tighten on slip.
    fn regulate(&mut self, k: &StepContext<'_>, now: &FingerInput<'_>, fused: &FusedContact) {
        let t = k.tuning;
        // While squeezing, `contact_sets` counts down the sets without contact that
        // `squeeze_unfelt` allows; a set with contact refills it.
        if self.phase == Phase::Squeeze {
            self.contact_sets = 3;
        }
        let watching = self.phase == Phase::Squeeze
            || (self.status == FingerStatus::ContactClosing && k.settled);
        if t.grasp.reflex && watching && self.lost_to_a_slide(k, now, fused) {
            return;
        }
        let force_n = self.force_n;
        let mut e = self.target_n - force_n;
        // Slow set rates: a held finger moves only when its half-second average leaves
        // the stable band, and then on that average.
        let slow_hold = k.rate.gain_scale < 1.0
            && self.phase == Phase::Hold
            && self.status == FingerStatus::ContactClosing;
        if slow_hold {
            e = self.target_n - self.slow_force_n;
        }
        if !(slow_hold && e.abs() <= t.stable_band * self.target_n) {
            self.drive_force(k, now, e);
        }
        let in_band = e.abs() <= t.stable_band * self.target_n.max(1e-6);
        // Stall at the cap: the current limit allows no more force. Straining there would
        // overload the servo, so the finger holds a little below what it reached and says
        // so.
        let pinned = self.phase == Phase::Squeeze && e > 0.0 && self.current_ma >= k.limit_ma - 1.0;
        if pinned {
            let (since_s, force0) = *self.cap_ref.get_or_insert((k.t_s, force_n));
            if force_n > force0 * (1.0 + t.stable_band) {
                self.cap_ref = Some((k.t_s, force_n));
                return;
            }
            if k.t_s - since_s >= t.stall_s {
                self.enter(Transition::ForceLimited {
                    target_n: force_n * (1.0 - 2.0 * t.stable_band),
                });
                return;
            }
        } else {
            self.cap_ref = None;
        }
        if self.phase == Phase::Squeeze {
            self.end_squeeze(k, fused, in_band);
        } else if self.status == FingerStatus::ContactClosing && k.settled && t.grasp.reflex {
            match k.held_slip {
                Some(slip) => self.slip_reflex(k, now, &slip),
                None => self.watch_slip(k, fused),
            }
        }
    }

    /// The goal current and the goal's lead for force error `e` (N): a PI term on the
    /// error over the free-motion current, within the limits.
    fn drive_force(&mut self, k: &StepContext<'_>, now: &FingerInput<'_>, e: f64) {
        let t = k.tuning;
        // What the loop acts on: an excess beyond the target counts as the target, so one
        // high reading (unfiltered at slow set rates) backs the finger off by no more than
        // the whole target would.
        let e_ctl = e.max(-self.target_n);
        let p = t.kp_ma_per_n * k.rate.gain_scale * e_ctl;
        let ki = t.ki_ma_per_n_s;
        let trial = self.feedforward_ma + p + self.integral_ma + ki * e_ctl * k.dt;
        let min = t.min_current_ma.min(k.limit_ma);
        // Anti-windup: integrate only while the output is not pinned in the direction the
        // error pushes.
        if !((trial >= k.limit_ma && e > 0.0) || (trial <= min && e < 0.0)) {
            self.integral_ma += ki * e_ctl * k.dt;
        }
        self.current_ma = (self.feedforward_ma + p + self.integral_ma).clamp(min, k.limit_ma);
        // The goal creeps by the force error: in current-based position mode the servo
        // holds a goal it has reached, so the force stops at the target instead of running
        // on to the current cap.
        let deg_per_n = self.stiffness.deg_per_n(t.squeeze_deg_per_n);
        let lead = (deg_per_n * e_ctl).clamp(-t.squeeze_lead_deg, t.squeeze_lead_deg);
        self.goal_deg = (now.present_deg + lead).min(now.close_deg.max(now.present_deg));
    }

    /// Where a squeeze ends: in the stable band for `Tuning::stable_s` it holds. Under
    /// `auto` the squeeze's target is only the preload, and slip felt under a load that
    /// came after the touch (a table dropping away, the arm lifting: the squeeze felt none
    /// for [`QUIET_BEFORE_LOAD_S`] first) hands the finger to the reflex at once, rather
    /// than after a squeeze that may not settle before the object has gone. A load there
    /// from the touch on is the squeeze's to settle first: the reflex raising a target that
    /// the force still lags would overshoot.
    fn end_squeeze(&mut self, k: &StepContext<'_>, fused: &FusedContact, in_band: bool) {
        let slip = k.grasp_slip.map(|s| s.state);
        if slip == Some(SlipState::None) {
            let t0 = *self.quiet_since_s.get_or_insert(k.t_s);
            self.quiet_seen |= k.t_s - t0 >= QUIET_BEFORE_LOAD_S;
        } else {
            self.quiet_since_s = None;
        }
        let loaded = slip.is_some_and(|s| s != SlipState::None);
        if k.auto_target && fused.contact && loaded && self.quiet_seen {
            self.enter(Transition::Stable);
        } else {
            self.settle(k, in_band);
        }
    }

    /// A squeeze that stays in the stable band for `Tuning::stable_s` holds.
    fn settle(&mut self, k: &StepContext<'_>, in_band: bool) {
        if in_band {
            let since = *self.stable_since_s.get_or_insert(k.t_s);
            if k.t_s - since >= k.tuning.stable_s {
                self.enter(Transition::Stable);
            }
        } else {
            self.stable_since_s = None;
        }
    }

    /// A squeezing or held finger whose contact is gone for [`LOST_SETS`] sets in a row
    /// within [`GIVE_UP_S`] of the grasp feeling slip has lost the object to a slide faster
    /// than the reflex: the grasp ends `slipping`, the finger holding where it is (closing
    /// on toward its target, it would squeeze blindly on nothing).
    fn lost_to_a_slide(
        &mut self,
        k: &StepContext<'_>,
        now: &FingerInput<'_>,
        fused: &FusedContact,
    ) -> bool {
        if k.grasp_slip.is_some_and(|s| s.state != SlipState::None) {
            self.slip_felt_at_s = Some(k.t_s);
        }
        self.lost_sets = if fused.contact { 0 } else { self.lost_sets + 1 };
        let felt = self
            .slip_felt_at_s
            .is_some_and(|t0| k.t_s - t0 <= GIVE_UP_S);
        if self.lost_sets >= LOST_SETS && felt {
            self.enter(Transition::Slipping {
                present_deg: now.present_deg,
            });
            return true;
        }
        false
    }

    /// Once the whole grasp holds, on a set whose slip is known: the target follows the
    /// least force that holds with the margin ([`reflex`]), between the request's target
    /// and `max_force_n`; a gross slip with the target at its most for [`GIVE_UP_S`] ends
    /// the grasp (`slipping`), the finger holding where it is.
    fn slip_reflex(&mut self, k: &StepContext<'_>, now: &FingerInput<'_>, slip: &SensorSlip) {
        let g = &k.tuning.grasp;
        let ceiling_n = g.max_force_n.max(self.floor_n);
        let dt = self
            .reflex_at_s
            .map_or(0.0, |t0| (k.t_s - t0).clamp(0.0, 0.5));
        self.reflex_at_s = Some(k.t_s);
        let ahead_n = if reflex::sliding(slip) {
            f64::INFINITY
        } else {
            self.least
                .ahead_n(k.t_s, reflex::least_n(self.force_n, slip))
        };
        let stopped_n = self.slide_stop.floor_n(k.t_s, self.force_n, slip);
        let aim_n = reflex::aim_n(g, ahead_n.max(stopped_n), slip, self.floor_n, ceiling_n);
        self.target_n = reflex::follow(g, self.target_n, aim_n, dt);
        self.aim_n = aim_n;
        if (self.target_n - self.moved_from_n).abs() > k.tuning.stable_band * self.moved_from_n {
            self.moved_from_n = self.target_n;
            self.moved_at_s = Some(k.t_s);
        }
        // Giving up takes the detector's own `gross`, not a low estimate: a low estimate at
        // the most force may be the estimate's bias on a contact that holds (docs/slip.md,
        // "The reflex"). At its most: the target there, and the force too (or the current
        // at its limit).
        let pressing_most = self.force_n >= (1.0 - k.tuning.stable_band) * ceiling_n
            || self.current_ma >= k.limit_ma - 1.0;
        if slip.state == SlipState::Gross && self.target_n >= ceiling_n && pressing_most {
            let since = *self.gross_since_s.get_or_insert(k.t_s);
            if k.t_s - since >= GIVE_UP_S {
                self.enter(Transition::Slipping {
                    present_deg: now.present_deg,
                });
            }
        } else {
            self.gross_since_s = None;
        }
    }

    /// Once the whole grasp holds, where no contact's slip is known: slip (the area falls or the centroid moves against the
    /// reference, on `Tuning::slip_sets` sets in a row) re-tightens.
    fn watch_slip(&mut self, k: &StepContext<'_>, fused: &FusedContact) {
        let t = k.tuning;
        let Some((area0, centroid0)) = self.slip_ref else {
            self.slip_ref = Some((fused.area_mm2, fused.centroid));
            return;
        };
        let area_drop = fused.area_mm2 < t.slip_area_share * area0;
        // A contact that grew by as much as a slip would shrink it is not a slip (an
        // object pushed in, or, at high camera noise, a spurious region): its centroid
        // moving does not count.
        let grew = fused.area_mm2 * t.slip_area_share > area0;
        let shifted = !grew
            && match (centroid0, fused.centroid) {
                (Some((s0, x0, y0)), Some((s1, x1, y1))) => {
                    s0 != s1 || (x1 - x0).hypot(y1 - y0) > t.slip_shift_mm
                }
                (Some(_), None) => true,
                _ => false,
            };
        self.slip_seen = if area_drop || shifted {
            // What a plain gel feels of a slide (for `lost_to_a_slide`).
            self.slip_felt_at_s = Some(k.t_s);
            self.slip_seen + 1
        } else {
            0
        };
        if self.slip_seen >= t.slip_sets {
            self.enter(Transition::Slip {
                factor: t.retighten_factor,
            });
        }
    }

    /// Back to the open position at the approach current.
    fn release(&mut self, k: &StepContext<'_>, now: &FingerInput<'_>) {
        self.goal_deg = now.open_deg;
        self.current_ma = k.tuning.approach_current_ma.min(k.limit_ma);
        if now.present_deg <= now.open_deg + 2.0 {
            self.enter(Transition::Opened);
        }
    }
}
