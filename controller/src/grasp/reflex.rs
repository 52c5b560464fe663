//! The slip reflex: how a held finger's force target follows the slip its contacts show.
//!
//! A marker gel's slip detector estimates each contact's stick ratio `s = c/a` (the share of
//! the contact's radius that still sticks; `docs/slip.md`). By Cattaneo–Mindlin,
//! `s = (1 − Q/μP)^(1/3)`, so the share of the grip that the load uses is `1 − s³`, and the
//! least grip that would just hold the load is `P × (1 − s³)`: what the measured slip and the
//! friction it implies require, without knowing either Q or μ. Over the grasp's contacts
//! the slip it holds by is that of the contact slipping most among those that bear their
//! share of the force ([`crate::fusion::SlipLoad`]): a light contact that slides whole
//! beside load-bearing ones that stick does not make the grasp slide. The reflex aims at
//! that force plus the settings' `slip_margin` (a gross slip aims at `max_force_n`), within
//! `[floor, max_force_n]`, and moves the target toward the aim at a bounded rate: up at
//! `reflex_rate_n_s`, down at [`RELAX_SHARE`] of it, so that a stable grasp relaxes slowly
//! toward the least force that holds and a load that grows is followed.

use super::settings::{GraspSettings, RELAX_SHARE};
use crate::fusion::{SensorSlip, SlipState};

/// A gross slip that the reflex, at its most, has not stopped for this long ends the grasp
/// (`slipping`), s.
pub const GIVE_UP_S: f64 = 1.0;

/// Below this estimated stick ratio a contact is taken as sliding. The detector's estimate
/// reads high where little sticks (a sliding contact reads 0.32 at the median and up to
/// 0.64, a true 0.4 reads 0.52: docs/slip.md, "The reflex"), so a low estimate is not
/// trusted to say how much more grip would hold.
pub const SLIDING_STICK_RATIO: f64 = 0.5;

/// The contact slides, or sticks so little that its estimate cannot be trusted.
pub fn sliding(slip: &SensorSlip) -> bool {
    slip.state == SlipState::Gross
        || slip.stick_ratio.is_nan()
        || slip.stick_ratio < SLIDING_STICK_RATIO
}

/// The least force that would just hold a finger pressing with `force_n` whose grasp slips
/// as `slip` (not sliding), N.
pub fn least_n(force_n: f64, slip: &SensorSlip) -> f64 {
    let force_n = if force_n.is_finite() {
        force_n.max(0.0)
    } else {
        0.0
    };
    force_n * slip.grip_used()
}

/// How far ahead the aim looks along the least force's rise, s: about the lag from a new
/// target to the force the fingers press with, so that a load that grows is met rather than
/// followed.
pub const LEAD_S: f64 = 0.15;
/// The least force and its rise are smoothed over this long, s.
const LEAST_SPAN_S: f64 = 0.1;

/// The least force that holds, smoothed, and how fast it rises.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LeastTrack {
    /// The last update's time, s.
    at_s: Option<f64>,
    /// The smoothed least force, N.
    least_n: f64,
    /// Its smoothed rise, N/s.
    rise_n_s: f64,
}

impl LeastTrack {
    /// Take the least force `least_n` at `t_s`; the force to aim at, `LEAD_S` ahead, N.
    pub fn ahead_n(&mut self, t_s: f64, least_n: f64) -> f64 {
        match self.at_s {
            Some(t0) if t_s > t0 => {
                let dt = (t_s - t0).min(0.5);
                let w = 1.0 - (-dt / LEAST_SPAN_S).exp();
                let smoothed = self.least_n + w * (least_n - self.least_n);
                let rise = (smoothed - self.least_n) / dt;
                self.rise_n_s += w * (rise - self.rise_n_s);
                self.least_n = smoothed;
            }
            Some(_) => {}
            None => {
                self.least_n = least_n;
                self.rise_n_s = 0.0;
            }
        }
        self.at_s = Some(t_s);
        self.least_n + LEAD_S * self.rise_n_s.max(0.0)
    }
}

/// How long the force at which a slide last stopped stands as a floor of the aim when the
/// contact's shear is too small to scale it by, s.
pub const STOP_MEMORY_S: f64 = 10.0;

/// A shear below this, mm, is too small to scale the floor by (a gel without markers
/// reads none).
const SHEAR_FLOOR_MM: f64 = 0.005;

/// The force at which the grasp last stopped sliding: measured, where the least force from
/// the stick ratio is a model. Relaxing below it with the margin would find the slide
/// again (and tighten again, a cycle of seconds), so the aim keeps above it, scaled by the
/// contact's shear now over its shear then (the shear grows with the tangential load, and
/// so does the least force that holds): while the load stays, the floor stays; when it
/// goes, the floor goes with it. Without a shear to scale by, the floor stands for
/// [`STOP_MEMORY_S`]. Only a slide counts ([`sliding`]): an `incipient` reading that comes
/// and goes on a contact that holds would ratchet the grip up.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SlideStop {
    /// The last set slid.
    sliding: bool,
    /// When (s), at what force (N) and what shear (mm) the last slide stopped.
    stopped: Option<(f64, f64, f64)>,
}

impl SlideStop {
    /// Take the set at `t_s`, the finger pressing `force_n` and the grasp slipping as
    /// `slip`: the floor the aim keeps, N (0 when no slide has stopped, or its floor has
    /// gone).
    pub fn floor_n(&mut self, t_s: f64, force_n: f64, slip: &SensorSlip) -> f64 {
        let now = sliding(slip);
        let shear_mm = shear_mm(slip);
        if self.sliding && !now && force_n.is_finite() {
            self.stopped = Some((t_s, force_n.max(0.0), shear_mm));
        }
        self.sliding = now;
        match self.stopped {
            Some((_, f, shear0)) if shear0 >= SHEAR_FLOOR_MM => f * (shear_mm / shear0).min(1.0),
            Some((t0, f, _)) if t_s - t0 <= STOP_MEMORY_S => f,
            _ => 0.0,
        }
    }
}

/// The size of a contact's shear, mm (0 when not finite).
fn shear_mm(slip: &SensorSlip) -> f64 {
    let s = slip.shear_mm[0].hypot(slip.shear_mm[1]);
    if s.is_finite() { s } else { 0.0 }
}

/// The force to aim at when the least that holds is `ahead_n` (looking ahead) and the
/// grasp slips as `slip`: that with the margin, within `[floor_n, ceiling_n]`; the ceiling
/// while it slides, N.
pub fn aim_n(
    settings: &GraspSettings,
    ahead_n: f64,
    slip: &SensorSlip,
    floor_n: f64,
    ceiling_n: f64,
) -> f64 {
    let ceiling_n = ceiling_n.max(floor_n);
    if sliding(slip) {
        // Sliding: how much more would hold is unknown, so the target rises at the rate.
        return ceiling_n;
    }
    let ahead_n = if ahead_n.is_finite() {
        ahead_n.max(0.0)
    } else {
        ceiling_n
    };
    (ahead_n * (1.0 + settings.slip_margin)).clamp(floor_n, ceiling_n)
}

/// `target_n` moved toward `aim_n` over `dt` s: up at the reflex's rate, down at
/// [`RELAX_SHARE`] of it.
pub fn follow(settings: &GraspSettings, target_n: f64, aim_n: f64, dt: f64) -> f64 {
    let up = settings.reflex_rate_n_s * dt;
    let down = up * RELAX_SHARE;
    target_n + (aim_n - target_n).clamp(-down, up)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slip(stick_ratio: f64, state: SlipState) -> SensorSlip {
        SensorSlip {
            shear_mm: [0.0, 0.0],
            stick_ratio,
            state,
        }
    }

    fn sheared(stick_ratio: f64, state: SlipState, shear_mm: f64) -> SensorSlip {
        SensorSlip {
            shear_mm: [shear_mm, 0.0],
            ..slip(stick_ratio, state)
        }
    }

    #[test]
    fn a_slide_that_stops_leaves_its_force_as_a_floor_while_its_load_stays() {
        let mut stop = SlideStop::default();
        assert_eq!(
            stop.floor_n(0.0, 0.3, &sheared(1.0, SlipState::None, 0.1)),
            0.0
        );
        // Incipient alone is not a slide.
        let incipient = sheared(0.8, SlipState::Incipient, 0.1);
        assert_eq!(stop.floor_n(0.1, 0.3, &incipient), 0.0);
        assert_eq!(
            stop.floor_n(0.2, 0.3, &sheared(1.0, SlipState::None, 0.1)),
            0.0
        );
        assert_eq!(
            stop.floor_n(0.3, 0.35, &sheared(0.8, SlipState::Gross, 0.1)),
            0.0
        );
        assert_eq!(
            stop.floor_n(0.4, 0.5, &sheared(0.9, SlipState::None, 0.1)),
            0.5
        );
        // The load stays (long after): so does the floor; never above the force itself.
        assert_eq!(
            stop.floor_n(60.0, 0.4, &sheared(1.0, SlipState::None, 0.2)),
            0.5
        );
        // Half the load: half the floor; none: none.
        assert!(
            (stop.floor_n(61.0, 0.4, &sheared(1.0, SlipState::None, 0.05)) - 0.25).abs() < 1e-12
        );
        assert_eq!(
            stop.floor_n(62.0, 0.4, &sheared(1.0, SlipState::None, 0.0)),
            0.0
        );
    }

    #[test]
    fn without_a_shear_the_floor_stands_for_a_while() {
        let mut stop = SlideStop::default();
        stop.floor_n(0.3, 0.35, &slip(0.2, SlipState::Gross));
        assert_eq!(stop.floor_n(0.4, 0.5, &slip(0.9, SlipState::None)), 0.5);
        assert_eq!(stop.floor_n(5.0, 0.4, &slip(1.0, SlipState::None)), 0.5);
        assert_eq!(stop.floor_n(10.5, 0.4, &slip(1.0, SlipState::None)), 0.0);
        // A non-finite force or shear leaves no floor.
        let mut stop = SlideStop::default();
        stop.floor_n(0.0, 0.3, &slip(0.2, SlipState::Incipient));
        assert_eq!(
            stop.floor_n(0.1, f64::NAN, &slip(1.0, SlipState::None)),
            0.0
        );
        let mut stop = SlideStop::default();
        stop.floor_n(0.0, 0.3, &sheared(0.2, SlipState::Incipient, f64::NAN));
        assert_eq!(
            stop.floor_n(0.1, 0.5, &sheared(1.0, SlipState::None, f64::INFINITY)),
            0.5
        );
    }

    #[test]
    fn the_aim_is_the_least_that_holds_with_the_margin_within_bounds() {
        let settings = GraspSettings {
            slip_margin: 0.2,
            ..GraspSettings::default()
        };
        let half = slip(0.5f64.cbrt(), SlipState::Incipient);
        // 2 N of which half is used: 1 N holds, 1.2 N with the margin.
        assert!((least_n(2.0, &half) - 1.0).abs() < 1e-12);
        assert!((aim_n(&settings, 1.0, &half, 0.3, 4.0) - 1.2).abs() < 1e-12);
        assert_eq!(
            aim_n(&settings, 0.0, &slip(1.0, SlipState::None), 0.3, 4.0),
            0.3
        );
        assert_eq!(
            aim_n(&settings, 0.1, &slip(0.9, SlipState::Gross), 0.3, 4.0),
            4.0
        );
        // A ceiling below the floor (a fixed target above max_force_n) keeps the floor.
        assert_eq!(
            aim_n(&settings, 10.0, &slip(0.0, SlipState::Gross), 5.0, 4.0),
            5.0
        );
        for bad in [f64::NAN, f64::INFINITY, -1.0] {
            let least = least_n(bad, &half);
            assert!(least.is_finite() && least >= 0.0, "{bad}: {least}");
            let a = aim_n(&settings, bad, &half, 0.3, 4.0);
            assert!(a.is_finite() && (0.3..=4.0).contains(&a), "{bad}: {a}");
        }
    }

    #[test]
    fn the_track_looks_ahead_along_a_rise_and_not_along_a_fall() {
        let mut rising = LeastTrack::default();
        let mut falling = LeastTrack::default();
        let mut ahead = (0.0, 0.0);
        for k in 0..120 {
            let t = k as f64 / 60.0;
            ahead = (
                rising.ahead_n(t, 1.0 + 2.0 * t),
                falling.ahead_n(t, 5.0 - 2.0 * t),
            );
        }
        let t = 119.0 / 60.0;
        // 2 N/s: 0.3 N ahead, less the smoothing's own lag (about 2 N/s × 0.1 s).
        assert!(
            (ahead.0 - (1.0 + 2.0 * t + 2.0 * (LEAD_S - LEAST_SPAN_S))).abs() < 0.02,
            "{}",
            ahead.0
        );
        assert!(
            (ahead.1 - (5.0 - 2.0 * t + 2.0 * LEAST_SPAN_S)).abs() < 0.02,
            "{}",
            ahead.1
        );
        // A repeated time changes nothing; the first reading is taken as it is.
        assert_eq!(rising.ahead_n(t, 100.0), ahead.0);
        assert_eq!(LeastTrack::default().ahead_n(0.0, 3.0), 3.0);
    }

    #[test]
    fn the_target_rises_at_the_rate_and_relaxes_at_a_tenth() {
        let settings = GraspSettings::default(); // 4 N/s
        assert!((follow(&settings, 1.0, 3.0, 0.1) - 1.4).abs() < 1e-12);
        assert!((follow(&settings, 1.0, 1.1, 0.1) - 1.1).abs() < 1e-12);
        assert!((follow(&settings, 1.0, 0.3, 0.1) - 0.96).abs() < 1e-12);
        assert_eq!(follow(&settings, 1.0, 0.3, 0.0), 1.0);
    }
}
