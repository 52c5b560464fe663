//! The `auto` grasp's lift, paced by the grip: the object's weight comes on at the rate
//! of a lift that takes `lift_rise_s`, but only while the grip keeps up. While the slip
//! reflex is still tightening toward what the felt slip asks
//! ([`GraspController::tightening`](crate::grasp::GraspController::tightening)), the
//! weight waits, as a person lifting an unknown object pauses when it starts to slip
//! and grips harder. The waits are bounded ([`LIFT_WAIT_MAX_S`] in all): a grip that
//! cannot catch up (held back by its current limit) does not stall the lift, and the
//! reflex's own give-up (`slipping`) then decides. The lift is over once the weight is on
//! and the settled force has stayed within [`LIFT_BAND`], the grip caught up, for
//! [`LIFT_STEADY_S`], or at the latest [`LIFT_TIMEOUT_S`] after the weight is on.
//!
//! This is pure bookkeeping on the task's clock; the task applies the share of the
//! weight it returns to the simulator's object ([`crate::runtime::ports::GroundTruth`]).

/// Once the weight is on, the grip has settled when its force has stayed within
/// [`LIFT_BAND`] for this long, s…
pub const LIFT_STEADY_S: f64 = 0.5;
/// …a share of the force…
pub const LIFT_BAND: f64 = 0.05;
/// …or, at the latest, this long after the weight is on, s.
pub const LIFT_TIMEOUT_S: f64 = 2.5;
/// The weight waits for the grip at most this long over the whole lift, s: from the
/// preload, the reflex reaches the most a finger may press (4 N by default, at 4 N/s)
/// within about a second, so a grip that is still tightening after five has met a limit
/// of its own.
pub const LIFT_WAIT_MAX_S: f64 = 5.0;

/// What the lift asks of the task after a set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LiftStep {
    /// Bring the object's load to this share of its weight over the next `over_s`.
    Load {
        /// The share of the weight, 0–1.
        share: f64,
        /// Over this long, s (the set period, so that the load rises smoothly).
        over_s: f64,
    },
    /// No finger holds the object any more: the lift is over, with no force settled on.
    Ungripped,
    /// The weight is on and the grip has settled at this force per finger, N.
    Settled {
        /// The force the grip settled on, N.
        force_n: f64,
    },
}

/// A lift under way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lift {
    /// A lift that keeps up brings the whole weight on over this long, s.
    rise_s: f64,
    /// The share of the weight on now, 0–1.
    share: f64,
    /// The last set's time, s.
    last_s: f64,
    /// How long the weight has waited for the grip so far, s.
    waited_s: f64,
    /// When the whole weight came on, s.
    weighed_at_s: Option<f64>,
    /// Since when (s), and at what force (N), the settled force has stayed steady.
    steady: Option<(f64, f64)>,
}

impl Lift {
    /// A lift that begins at `t_s` with none of the weight on, bringing it all on over
    /// `rise_s` while the grip keeps up (at once when `rise_s` is 0 or not finite).
    pub fn begin(t_s: f64, rise_s: f64) -> Self {
        let rise_s = if rise_s.is_finite() {
            rise_s.max(0.0)
        } else {
            0.0
        };
        Self {
            rise_s,
            share: 0.0,
            last_s: t_s,
            waited_s: 0.0,
            weighed_at_s: None,
            steady: None,
        }
    }

    /// The share of the weight on now, 0–1.
    pub fn share(&self) -> f64 {
        self.share
    }

    /// How long the weight has waited for the grip so far, s.
    pub fn waited_s(&self) -> f64 {
        self.waited_s
    }

    /// Take the set at `t_s`: whether the grip is still `tightening`, and the force it has
    /// settled on (`None`: no finger holds). Returns what to do next.
    pub fn step(&mut self, t_s: f64, tightening: bool, settled_n: Option<f64>) -> LiftStep {
        let dt = if t_s > self.last_s {
            (t_s - self.last_s).min(0.5)
        } else {
            0.0
        };
        self.last_s = t_s;
        if self.weighed_at_s.is_none() {
            let waits = tightening && self.waited_s < LIFT_WAIT_MAX_S;
            if waits {
                self.waited_s += dt;
            } else if self.rise_s > 0.0 {
                self.share = (self.share + dt / self.rise_s).min(1.0);
            } else {
                self.share = 1.0;
            }
            if self.share >= 1.0 {
                self.weighed_at_s = Some(t_s);
            }
        }
        match (self.weighed_at_s, settled_n) {
            (Some(at_s), Some(force_n)) => self.settle(t_s, at_s, force_n, tightening, dt),
            (_, None) => LiftStep::Ungripped,
            (None, Some(_)) => LiftStep::Load {
                share: self.share,
                over_s: dt,
            },
        }
    }

    /// With the weight on since `at_s`: settled once the force has stayed steady with the
    /// grip caught up (or at the timeout), else keep the load.
    fn settle(&mut self, t_s: f64, at_s: f64, force_n: f64, tightening: bool, dt: f64) -> LiftStep {
        let steady = match self.steady {
            Some((since, f0)) if !tightening && (force_n - f0).abs() <= LIFT_BAND * f0 => {
                (since, f0)
            }
            _ => (t_s, force_n),
        };
        self.steady = Some(steady);
        if t_s - steady.0 >= LIFT_STEADY_S || t_s - at_s >= LIFT_TIMEOUT_S {
            LiftStep::Settled { force_n }
        } else {
            LiftStep::Load {
                share: 1.0,
                over_s: dt,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Run a lift at 24 sets a second, tightening while `tight(t)`, its grip steady at
    /// 1 N: the time the weight was on and the time it settled, s.
    fn run(rise_s: f64, tight: impl Fn(f64) -> bool) -> (Lift, Option<f64>, f64) {
        let mut lift = Lift::begin(0.0, rise_s);
        let mut weighed = None;
        for k in 1..2400 {
            let t = k as f64 / 24.0;
            let step = lift.step(t, tight(t), Some(1.0));
            if weighed.is_none() && lift.share() >= 1.0 {
                weighed = Some(t);
            }
            if let LiftStep::Settled { force_n } = step {
                assert_eq!(force_n, 1.0);
                return (lift, weighed, t);
            }
            let LiftStep::Load { share, over_s } = step else {
                unreachable!()
            };
            assert!((0.0..=1.0).contains(&share) && over_s > 0.0 && over_s.is_finite());
        }
        panic!("the lift never settled");
    }

    #[test]
    fn a_grip_that_keeps_up_takes_the_weight_over_the_rise() {
        let (lift, weighed, settled) = run(0.5, |_| false);
        let weighed = weighed.expect("the weight came on");
        assert!((weighed - 0.5).abs() <= 1.0 / 24.0 + 1e-9, "{weighed}");
        assert!((settled - weighed - LIFT_STEADY_S).abs() <= 1.0 / 24.0 + 1e-9);
        assert_eq!(lift.waited_s(), 0.0);
    }

    #[test]
    fn the_weight_waits_while_the_grip_tightens() {
        // Tightening from 0.1 s to 1.1 s: the weight is on a second later.
        let (lift, weighed, _) = run(0.5, |t| (0.1..1.1).contains(&t));
        let weighed = weighed.expect("the weight came on");
        assert!((weighed - 1.5).abs() <= 2.0 / 24.0, "{weighed}");
        assert!((lift.waited_s() - 1.0).abs() <= 2.0 / 24.0);
    }

    #[test]
    fn a_grip_that_never_catches_up_stalls_the_lift_only_so_long() {
        let (lift, weighed, settled) = run(0.5, |_| true);
        let weighed = weighed.expect("the weight came on");
        assert!((lift.waited_s() - LIFT_WAIT_MAX_S).abs() <= 1.0 / 24.0 + 1e-9);
        assert!(weighed <= LIFT_WAIT_MAX_S + 0.5 + 2.0 / 24.0, "{weighed}");
        assert!(settled - weighed <= LIFT_TIMEOUT_S + 1e-9);
    }

    #[test]
    fn no_rise_or_a_bad_one_puts_the_weight_on_at_once() {
        for rise in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let mut lift = Lift::begin(0.0, rise);
            let step = lift.step(1.0 / 24.0, false, Some(1.0));
            assert_eq!(lift.share(), 1.0, "{rise}");
            assert!(matches!(step, LiftStep::Load { share, .. } if share == 1.0));
        }
    }

    #[test]
    fn a_force_that_wanders_restarts_the_steady_wait_and_the_timeout_ends_it() {
        let mut lift = Lift::begin(0.0, 0.0);
        let mut t = 0.0;
        let mut settled_at = None;
        for k in 1..200 {
            t = k as f64 / 24.0;
            // ±10% each set: never steady within the 5% band.
            let force = if k % 2 == 0 { 1.1 } else { 0.9 };
            if let LiftStep::Settled { force_n } = lift.step(t, false, Some(force)) {
                assert!(force_n.is_finite());
                settled_at = Some(t);
                break;
            }
        }
        let settled_at = settled_at.unwrap_or(t);
        assert!((settled_at - 1.0 / 24.0 - LIFT_TIMEOUT_S).abs() <= 1.0 / 24.0 + 1e-9);
    }

    #[test]
    fn no_finger_holding_ends_the_lift() {
        let mut lift = Lift::begin(0.0, 0.5);
        assert_eq!(lift.step(0.1, false, None), LiftStep::Ungripped);
    }
}
