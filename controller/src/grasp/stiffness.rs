//! The contact's stiffness as the force loop sees it, and the loop's gain from it.
//!
//! A squeezing or holding finger moves its goal by `squeeze_deg_per_n` degrees per newton
//! of force error each set; the servo reaches the goal within the set, so the force moves
//! by that step times the contact's stiffness (N per degree of the servo's shaft: the gel,
//! the object and the cable in series). That product is the loop's gain per set. With the
//! force read a set or two late (the median of three and the average behind it), the loop
//! rings once the gain nears 0.6 and oscillates beyond it: a full 1.5 kg can at 80 N/mm
//! held at 4 N shows 3.7 N/deg, a gain of 0.9, and a cycle of 0.4 s from 2 N to 6 N
//! (docs/control.md, "Stiff contacts"). Soft objects are far below it (the tennis ball's
//! contact is a fraction of a newton per degree).
//!
//! [`StiffnessTrack`] estimates the stiffness online from the finger's own motion, a
//! forgetting least-squares slope of the force's change over the position's between sets,
//! and [`StiffnessTrack::deg_per_n`] caps the goal's step so that the gain stays at
//! [`LOOP_GAIN`]: the nominal gain where the contact is soft, less where it is stiff.

/// The loop's gain per set that the goal's step keeps to (half of where a loop with two
/// sets of delay starts to ring).
pub const LOOP_GAIN: f64 = 0.3;
/// Steps of the position smaller than this are not informative, degrees (the servo's
/// resolution is 0.088°).
const MIN_STEP_DEG: f64 = 0.02;
/// Each informative step keeps this share of what the steps before it said.
const FORGET: f64 = 0.8;
/// The estimate speaks once its steps add up to this much motion, degrees².
const MIN_MOTION_DEG2: f64 = 0.02;

/// The step never falls below this share of the nominal one (a reading that made the
/// contact look rigid must not freeze the finger).
const MIN_STEP_SHARE: f64 = 0.02;

/// A forgetting least-squares estimate of the force's slope over the finger's position.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StiffnessTrack {
    /// The last set's position (degrees) and force (N).
    last: Option<(f64, f64)>,
    /// Σ Δx² and Σ Δx·ΔF over the informative steps, forgotten by [`FORGET`] each.
    sxx: f64,
    sxf: f64,
}

impl StiffnessTrack {
    /// Take a set's position (degrees) and force as read (N). Non-finite values are
    /// skipped.
    pub fn observe(&mut self, position_deg: f64, force_n: f64) {
        if !(position_deg.is_finite() && force_n.is_finite()) {
            return;
        }
        if let Some((x0, f0)) = self.last {
            let dx = position_deg - x0;
            if dx.abs() >= MIN_STEP_DEG {
                self.sxx = FORGET * self.sxx + dx * dx;
                self.sxf = FORGET * self.sxf + dx * (force_n - f0);
                if !(self.sxx.is_finite() && self.sxf.is_finite()) {
                    (self.sxx, self.sxf) = (0.0, 0.0); // a reading out of range: start over
                }
            }
        }
        self.last = Some((position_deg, force_n));
    }

    /// The stiffness, N per degree, once enough motion has been seen (`None` before).
    pub fn n_per_deg(&self) -> Option<f64> {
        (self.sxx >= MIN_MOTION_DEG2).then(|| self.sxf / self.sxx)
    }

    /// The goal's step per newton of force error: `nominal_deg_per_n`, or less where the
    /// contact is stiff enough that the loop's gain would pass [`LOOP_GAIN`].
    pub fn deg_per_n(&self, nominal_deg_per_n: f64) -> f64 {
        match self.n_per_deg() {
            Some(k) if k * nominal_deg_per_n > LOOP_GAIN => {
                (LOOP_GAIN / k).max(MIN_STEP_SHARE * nominal_deg_per_n)
            }
            _ => nominal_deg_per_n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A contact of `k` N/deg from 10°, stepped through `steps`.
    fn track_on(k: f64, steps: &[f64]) -> StiffnessTrack {
        let mut t = StiffnessTrack::default();
        let mut x = 10.0;
        t.observe(x, 0.0);
        for dx in steps {
            x += dx;
            t.observe(x, k * (x - 10.0));
        }
        t
    }

    #[test]
    fn a_linear_contact_is_measured_and_a_stiff_one_lowers_the_step() {
        let t = track_on(3.7, &[0.3, -0.2, 0.4, -0.1, 0.25]);
        let k = t.n_per_deg().expect("enough motion");
        assert!((k - 3.7).abs() < 1e-9, "{k}");
        let step = t.deg_per_n(0.25);
        assert!((step * k - LOOP_GAIN).abs() < 1e-9, "{step}");
        // A soft contact keeps the nominal step.
        let soft = track_on(0.4, &[0.3, -0.2, 0.4, -0.1, 0.25]);
        assert_eq!(soft.deg_per_n(0.25), 0.25);
    }

    #[test]
    fn too_little_motion_says_nothing_and_keeps_the_nominal_step() {
        // Below the servo's resolution, and too few steps.
        let t = track_on(50.0, &[0.001, -0.001, 0.002, 0.05]);
        assert_eq!(t.n_per_deg(), None);
        assert_eq!(t.deg_per_n(0.25), 0.25);
    }

    #[test]
    fn the_estimate_follows_a_contact_that_stiffens() {
        let mut t = track_on(0.5, &[0.2; 10]);
        let mut x = 12.0;
        let mut f = t.last.map_or(0.0, |l| l.1);
        for _ in 0..20 {
            x += 0.2;
            f += 4.0 * 0.2;
            t.observe(x, f);
        }
        let k = t.n_per_deg().expect("enough motion");
        assert!((k - 4.0).abs() < 0.1, "{k}");
    }

    #[test]
    fn bad_readings_never_give_a_non_finite_step() {
        let mut t = StiffnessTrack::default();
        for (x, f) in [
            (f64::NAN, 1.0),
            (1.0, f64::INFINITY),
            (1.0, 0.0),
            (1.0, 5.0),
            (1.5, -3.0),
            (1.0, 1e300),
            (2.0, -1e300),
        ] {
            t.observe(x, f);
            let step = t.deg_per_n(0.25);
            assert!(step.is_finite() && step > 0.0, "{step}");
        }
    }
}
