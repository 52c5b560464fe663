//! Cable-driven finger mechanics, quasi-static: the servo winds the cable, the cable flexes
//! the joints against their return springs and whatever the sensor pads press on.
//!
//! Geometry comes from the layout's `[[fingers]]` ([`FingerSpec`]); a finger with three
//! phalanges needs no code change. Per joint `j` with flexion `q_j` (0 at rest, up to its
//! limit) the equilibrium is
//!
//! ```text
//! T·a_j = preload_j + k_j·q_j + τ_contact,j(q)        T = k_cable · max(0, L − Σ a_i·q_i)
//! ```
//!
//! where `L` is the cable the servo has taken up past the slack, `a_j` the moment arms and
//! `τ_contact,j` the torque about joint `j` of every pad force on that phalanx or beyond.
//! [`FingerMechanics::relax`] solves it by damped Gauss–Seidel Newton sweeps (the joint
//! stiffness from cable, spring and each pad's contact stiffness times its lever squared),
//! warm-started from the previous step, so a couple of sweeps per step track the servo.

use glam::DVec3;

use gelgrip_controller::fingers::FingerSpec;

/// Cable stiffness, N/mm (a short braided line with its terminations).
pub const CABLE_N_PER_MM: f64 = 200.0;
/// Largest joint change per sweep, rad (keeps the Newton steps safe across contact onset).
const MAX_STEP_RAD: f64 = 0.05;

/// Where a sensor pad is: its centre, outward normal and image axes (unit vectors).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadFrame {
    /// Centre of the gel surface, mm, gripper frame.
    pub center: DVec3,
    /// Unit normal out of the gel, toward what it touches.
    pub normal: DVec3,
    /// Image x (columns).
    pub ex: DVec3,
    /// Image y (rows).
    pub ey: DVec3,
}

/// What pushes on one pad: the normal force and where it acts.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PadLoad {
    /// Normal force, N (pushes the pad back along −normal).
    pub force_n: f64,
    /// Centre of pressure, mm, gripper frame.
    pub point: DVec3,
    /// How fast the force grows with further indentation, N/mm.
    pub stiffness_n_per_mm: f64,
}

/// One finger's state.
#[derive(Debug, Clone)]
pub struct FingerMechanics {
    spec: FingerSpec,
    base: DVec3,
    inward: DVec3,
    /// Joint flexions, rad.
    q: Vec<f64>,
    tension_n: f64,
}

impl FingerMechanics {
    /// A finger at rest.
    pub fn new(spec: FingerSpec) -> Self {
        let yaw = spec.yaw_deg.to_radians();
        let n = spec.phalanges.len();
        Self {
            base: DVec3::from_array(spec.base_xyz_mm),
            inward: -DVec3::new(yaw.cos(), yaw.sin(), 0.0),
            q: vec![0.0; n],
            tension_n: 0.0,
            spec,
        }
    }

    /// The geometry.
    pub fn spec(&self) -> &FingerSpec {
        &self.spec
    }

    /// Joint flexions, rad.
    pub fn joints_rad(&self) -> &[f64] {
        &self.q
    }

    /// Cable tension, N.
    pub fn tension_n(&self) -> f64 {
        self.tension_n
    }

    /// Torque the cable puts on the servo shaft, N·m.
    pub fn servo_load_nm(&self) -> f64 {
        self.tension_n * self.spec.pulley_radius_mm / 1000.0
    }

    /// Cable taken up past the slack for a servo at `servo_deg`, mm (negative = slack).
    pub fn cable_mm(&self, servo_deg: f64) -> f64 {
        servo_deg.to_radians() * self.spec.pulley_radius_mm - self.spec.cable_slack_mm
    }

    /// (joint position, unit direction, unit inner normal) of every phalanx for flexions `q`.
    fn chain(&self, q: &[f64]) -> Vec<(DVec3, DVec3, DVec3)> {
        let up = DVec3::Z;
        let mut at = self.base;
        let mut phi = 0.0;
        let mut out = Vec::with_capacity(q.len());
        for (p, qj) in self.spec.phalanges.iter().zip(q) {
            phi += p.rest_deg.to_radians() + qj;
            let dir = up * phi.cos() + self.inward * phi.sin();
            let normal = -up * phi.sin() + self.inward * phi.cos();
            out.push((at, dir, normal));
            at += dir * p.length_mm;
        }
        out
    }

    /// The pad frame of phalanx `i` for flexions `q`.
    fn pad_at(&self, q: &[f64], i: usize) -> Option<PadFrame> {
        let (joint, dir, normal) = *self.chain(q).get(i)?;
        let p = &self.spec.phalanges[i];
        Some(PadFrame {
            center: joint + dir * p.pad_offset_mm + normal * p.pad_standoff_mm,
            normal,
            ex: dir.cross(normal),
            ey: dir,
        })
    }

    /// The pad frame of phalanx `i` now.
    pub fn pad(&self, i: usize) -> Option<PadFrame> {
        self.pad_at(&self.q, i)
    }

    /// Unbalanced torque at joint `j` in pose `q` (N·mm, positive flexes the joint) and how
    /// fast it falls as the joint flexes (N·mm/rad): cable, spring and every pad beyond.
    fn residual(
        &self,
        q: &[f64],
        j: usize,
        cable_mm: f64,
        contact: &mut dyn FnMut(usize, &PadFrame) -> PadLoad,
    ) -> (f64, f64) {
        let taken: f64 = self
            .spec
            .phalanges
            .iter()
            .zip(q)
            .map(|(p, qi)| p.moment_arm_mm * qi)
            .sum();
        let stretch = cable_mm - taken;
        let tension = CABLE_N_PER_MM * stretch.max(0.0);
        let p = &self.spec.phalanges[j];
        let chain = self.chain(q);
        let (joint, _, _) = chain[j];
        let mut resist = p.spring_preload_nmm + p.spring_nmm_per_rad * q[j];
        let mut stiffness = p.spring_nmm_per_rad;
        if stretch > 0.0 {
            stiffness += CABLE_N_PER_MM * p.moment_arm_mm * p.moment_arm_mm;
        }
        for (i, (_, dir, normal)) in chain.iter().enumerate().skip(j) {
            let Some(pad) = self.pad_at(q, i) else {
                continue;
            };
            let load = contact(i, &pad);
            if load.force_n > 0.0 {
                let axis = dir.cross(*normal);
                let lever = (load.point - joint).cross(pad.normal).dot(axis);
                resist += load.force_n * lever;
                stiffness += load.stiffness_n_per_mm * lever * lever;
            }
        }
        (tension * p.moment_arm_mm - resist, stiffness)
    }

    /// Bring the joints to equilibrium for `cable_mm` of cable taken up, with `contact`
    /// giving the load on phalanx `i`'s pad in a trial pose; `sweeps` Gauss–Seidel sweeps.
    pub fn relax(
        &mut self,
        cable_mm: f64,
        sweeps: usize,
        contact: &mut dyn FnMut(usize, &PadFrame) -> PadLoad,
    ) {
        let cable_mm = if cable_mm.is_finite() { cable_mm } else { 0.0 };
        let mut q = self.q.clone();
        for _ in 0..sweeps {
            for j in 0..q.len() {
                let limit = self.spec.phalanges[j].limit_deg.to_radians();
                let (r0, stiffness) = self.residual(&q, j, cable_mm, contact);
                let step = (r0 / stiffness.max(1e-3)).clamp(-MAX_STEP_RAD, MAX_STEP_RAD);
                if step.is_finite() {
                    q[j] = (q[j] + step).clamp(0.0, limit);
                }
            }
        }
        let taken: f64 = self
            .spec
            .phalanges
            .iter()
            .zip(&q)
            .map(|(p, qi)| p.moment_arm_mm * qi)
            .sum();
        self.tension_n = CABLE_N_PER_MM * (cable_mm - taken).max(0.0);
        self.q = q;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gelgrip_controller::layout::HandLayout;

    fn three_finger() -> HandLayout {
        let text = include_str!("../../../configs/layouts/three-finger.toml");
        HandLayout::from_toml("three-finger.toml", text).expect("layout")
    }

    fn free(_: usize, _: &PadFrame) -> PadLoad {
        PadLoad::default()
    }

    #[test]
    fn slack_cable_leaves_the_finger_open() {
        let mut f = FingerMechanics::new(three_finger().fingers[0].clone());
        f.relax(f.cable_mm(5.0), 20, &mut free);
        assert!(f.joints_rad().iter().all(|q| *q == 0.0));
        assert_eq!(f.tension_n(), 0.0);
    }

    #[test]
    fn winding_flexes_every_joint_and_the_tension_matches_the_springs() {
        let mut f = FingerMechanics::new(three_finger().fingers[0].clone());
        let mut last = vec![0.0; 2];
        for deg in [20.0, 40.0, 60.0, 80.0] {
            for _ in 0..50 {
                f.relax(f.cable_mm(deg), 4, &mut free);
            }
            let q = f.joints_rad().to_vec();
            // The middle joint leads; the tip's stiffer preload holds it until the tension
            // is high enough.
            assert!(
                q.iter().zip(&last).all(|(a, b)| a >= b) && q[0] > last[0],
                "{deg}: {q:?}"
            );
            for (j, p) in f.spec().phalanges.iter().enumerate() {
                if q[j] > 0.0 && q[j] < p.limit_deg.to_radians() {
                    let spring = p.spring_preload_nmm + p.spring_nmm_per_rad * q[j];
                    let cable = f.tension_n() * p.moment_arm_mm;
                    assert!(
                        (spring - cable).abs() < 1.0,
                        "joint {j}: {spring} vs {cable}"
                    );
                }
            }
            last = q;
        }
        assert!(last.iter().all(|q| *q > 0.0), "{last:?}");
    }

    #[test]
    fn joints_stop_at_their_limits_and_tension_then_rises() {
        let mut f = FingerMechanics::new(three_finger().fingers[0].clone());
        for _ in 0..400 {
            f.relax(f.cable_mm(179.0), 4, &mut free);
        }
        for (q, p) in f.joints_rad().iter().zip(&f.spec().phalanges) {
            assert!((q - p.limit_deg.to_radians()).abs() < 1e-9);
        }
        assert!(f.tension_n() > 100.0, "{}", f.tension_n());
    }

    #[test]
    fn flexion_swings_the_pads_toward_the_palm_axis() {
        let mut f = FingerMechanics::new(three_finger().fingers[0].clone());
        let open = f.pad(1).expect("tip pad");
        for _ in 0..100 {
            f.relax(f.cable_mm(90.0), 4, &mut free);
        }
        let closed = f.pad(1).expect("tip pad");
        let radius = |p: DVec3| (p.x * p.x + p.y * p.y).sqrt();
        assert!(radius(closed.center) < radius(open.center) - 10.0);
        assert!((open.normal.length() - 1.0).abs() < 1e-12);
        assert!(open.normal.dot(open.ex).abs() < 1e-12 && open.ex.dot(open.ey).abs() < 1e-12);
    }
}
