//! What the gripper can do, as bounds on a grasp request: the force per finger that the
//! current cap can produce, the servo's no-load speed, and the longest a grasp may take.
//! The grasp API ([`crate::gripper::GripperHandle::validate`]), the CLI's gentle grasp and
//! task scripts all refuse values outside these, with a message that names the range and
//! where it comes from (`docs/control.md`, "Grasp limits").
//!
//! The force bound is a statics upper bound, with no return springs and no friction, so it
//! is generous: every force the controller can reach stays accepted. A servo at current
//! `I` (the request's cap, at most the configured Current Limit and the stall current)
//! winds its cable with tension `T = τ_stall × I / I_stall / r_pulley`; that tension presses
//! a pad about its own joint with `T × moment_arm / pad_offset`; a finger's bound is the
//! sum over its pads, and a request's is the smallest over the fingers taking part.

use crate::actuator::ServoRating;
use crate::gripper::GripperError;
use crate::layout::HandLayout;

use super::GraspRequest;

/// Longest a grasp may take before it gives up (a request's `timeout_s`), s: the grasp
/// API's documented bound (`docs/api.md`), the CLI's `--task-timeout` and the gentle
/// grasp's.
pub const MAX_TIMEOUT_S: f64 = 120.0;

/// A pad nearer its joint than this counts at this distance, mm: a pad has a size, and the
/// lever `moment_arm / pad_offset` stays finite for a layout with `pad_offset_mm = 0`.
const MIN_PAD_OFFSET_MM: f64 = 1.0;

/// One finger's reach: the force its pads can press with per mA of servo current.
#[derive(Debug, Clone, PartialEq)]
struct FingerReach {
    /// `f1`, `f2`, …
    id: String,
    /// Force per mA of current cap, summed over the finger's pads, N per mA.
    n_per_ma: f64,
}

/// The bounds of a grasp request on one hand, its servos and their current cap.
#[derive(Debug, Clone, PartialEq)]
pub struct GraspLimits {
    fingers: Vec<FingerReach>,
    rating: ServoRating,
    current_limit_ma: f64,
}

/// `v` for a message: plain for ordinary magnitudes, in exponent form for huge or tiny ones
/// (`1e308`, not 309 digits).
pub fn number(v: f64) -> String {
    let a = v.abs();
    if !v.is_finite() || v == 0.0 || (1e-4..1e6).contains(&a) {
        v.to_string()
    } else {
        format!("{v:e}")
    }
}

/// `v` rounded down to 0.1: a bound stated with one decimal is the bound applied.
fn floor_tenth(v: f64) -> f64 {
    (v * 10.0).floor() / 10.0
}

impl GraspLimits {
    /// The limits of `layout`'s fingers driven by servos rated `rating`, whose Current
    /// Limit is `current_limit_ma` (the configured `servos.current_limit_ma`).
    pub fn for_hand(layout: &HandLayout, rating: ServoRating, current_limit_ma: f64) -> Self {
        let torque_nmm_per_ma = rating.torque_nm_per_ma() * 1000.0;
        let fingers = layout
            .fingers
            .iter()
            .map(|f| {
                let lever: f64 = f
                    .phalanges
                    .iter()
                    .map(|p| p.moment_arm_mm / p.pad_offset_mm.max(MIN_PAD_OFFSET_MM))
                    .sum();
                FingerReach {
                    id: f.id.clone(),
                    // The cable's tension per mA (N), times the pads' levers.
                    n_per_ma: torque_nmm_per_ma / f.pulley_radius_mm * lever,
                }
            })
            .collect();
        Self {
            fingers,
            rating,
            current_limit_ma,
        }
    }

    /// The servos' ratings.
    pub fn rating(&self) -> &ServoRating {
        &self.rating
    }

    /// The current a request capped at `requested_ma` can reach, mA: at most the configured
    /// Current Limit and the servo's stall current.
    pub fn cap_ma(&self, requested_ma: f64) -> f64 {
        let configured = if self.current_limit_ma.is_finite() {
            self.current_limit_ma.max(0.0)
        } else {
            0.0
        };
        let requested = if requested_ma.is_finite() {
            requested_ma.max(0.0)
        } else {
            configured
        };
        requested.min(configured).min(self.rating.stall_current_ma)
    }

    /// Each finger's largest force at a current cap of `requested_ma`, N, rounded down to
    /// 0.1 N (0 for an index beyond the hand).
    fn finger_max_n(&self, finger: usize, requested_ma: f64) -> f64 {
        self.fingers.get(finger).map_or(0.0, |f| {
            let v = floor_tenth(f.n_per_ma * self.cap_ma(requested_ma));
            if v.is_finite() { v.max(0.0) } else { 0.0 }
        })
    }

    /// The largest force per finger that `fingers` can all press with at a current cap of
    /// `requested_ma`, N, rounded down to 0.1 N (0 when `fingers` is empty).
    pub fn max_force_n(&self, fingers: &[usize], requested_ma: f64) -> f64 {
        fingers
            .iter()
            .map(|&f| self.finger_max_n(f, requested_ma))
            .reduce(f64::min)
            .unwrap_or(0.0)
    }

    /// Why the force bound of `fingers` at `requested_ma` is what it is: `what f1, f2, f3
    /// can press with at the 1000 mA current cap` (the fingers named are those that set
    /// it).
    pub fn force_reason(&self, fingers: &[usize], requested_ma: f64) -> String {
        let max = self.max_force_n(fingers, requested_ma);
        let mut ids: Vec<&str> = Vec::new();
        for &f in fingers {
            if let Some(reach) = self.fingers.get(f)
                && self.finger_max_n(f, requested_ma) <= max
                && !ids.contains(&reach.id.as_str())
            {
                ids.push(&reach.id);
            }
        }
        format!(
            "what {} can press with at the {} mA current cap",
            ids.join(", "),
            number(self.cap_ma(requested_ma))
        )
    }

    /// The fastest a finger's servo turns, deg/s: its no-load speed.
    pub fn max_speed_deg_s(&self) -> f64 {
        self.rating.no_load_deg_s()
    }

    /// Why the speed bound is what it is: `the XM430-W350's no-load speed, 46 rpm at 12 V`.
    pub fn speed_reason(&self) -> String {
        self.rating.no_load_speed_text()
    }

    /// Check `request` against these limits: its current cap and fingers, then its force,
    /// speed and timeout, each refused outside its range with the range and its reason.
    pub fn check(&self, request: &GraspRequest) -> Result<(), GripperError> {
        let invalid = |field: &'static str, value: f64, expected: String| {
            Err(GripperError::InvalidRequest {
                field,
                value: number(value),
                expected,
            })
        };
        let within = |v: f64, max: f64| v.is_finite() && v > 0.0 && v <= max;
        let current = request.current_limit_ma;
        if !(current.is_finite() && current >= 0.0) {
            return invalid(
                "current_limit_ma",
                current,
                "a finite current of at least 0 mA".into(),
            );
        }
        if request.fingers.is_empty() || request.fingers.iter().any(|&f| f >= self.fingers.len()) {
            return Err(GripperError::InvalidRequest {
                field: "fingers",
                value: format!("{:?}", request.fingers),
                expected: format!("finger indices below {}, at least one", self.fingers.len()),
            });
        }
        let max_force = self.max_force_n(&request.fingers, current);
        if !within(request.target_force_n, max_force) {
            return invalid(
                "target_force_n",
                request.target_force_n,
                format!(
                    "a force per finger in (0, {}] N: {}",
                    number(max_force),
                    self.force_reason(&request.fingers, current)
                ),
            );
        }
        let max_speed = self.max_speed_deg_s();
        if !within(request.speed_deg_s, max_speed) {
            return invalid(
                "speed_deg_s",
                request.speed_deg_s,
                format!(
                    "a speed in (0, {}] deg/s: {}",
                    number(max_speed),
                    self.speed_reason()
                ),
            );
        }
        if !within(request.timeout_s, MAX_TIMEOUT_S) {
            return invalid(
                "timeout_s",
                request.timeout_s,
                format!(
                    "a timeout in (0, {}] s: the longest a grasp may take",
                    number(MAX_TIMEOUT_S)
                ),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
