//! The force loop on a stiff contact: an elastic finger (the force is the contact's
//! stiffness times the press past the contact angle; the servo reaches its goal within the
//! set, and the next set shows the force there, as on the simulated hand). At the nominal
//! 0.25° per N a contact of 10 N/deg cycles here between 0 and 18 N around a 4 N target;
//! the simulated steel can cycled at 3.7 N/deg already (docs/control.md, "Stiff
//! contacts"), its gel and object adding lag this toy lacks. The measured stiffness keeps
//! every one steady.

use super::*;

const CONTACT_DEG: f64 = 40.0;
const RATE_HZ: f64 = 24.0;

/// An elastic contact of `n_per_deg`.
struct ElasticFinger {
    position_deg: f64,
    n_per_deg: f64,
    /// The force now, N: what the next set shows, with the position the servo reports.
    force_n: f64,
}

impl ElasticFinger {
    fn step(&mut self, goal: &FingerGoal, dt: f64) {
        let max_step = 90.0 * dt;
        let wanted =
            self.position_deg + (goal.position_deg - self.position_deg).clamp(-max_step, max_step);
        // The goal is reached within the set: the current cap stands well above what the
        // contact pushes back with, as on the simulated can (350 mA against 4 N).
        self.position_deg = wanted;
        self.force_n = self.n_per_deg * (self.position_deg - CONTACT_DEG).max(0.0);
    }

    fn contact(&self) -> FusedContact {
        toy_contact(self.force_n)
    }
}

/// The forces over the last two seconds of a 20 s grasp at `target_n` on contacts of
/// `n_per_deg`.
fn held_forces(n_per_deg: f64, target_n: f64) -> Vec<f64> {
    let mut ctl = GraspController::new(
        request(target_n),
        Tuning::default(),
        vec![150.0; 3],
        vec![0.0; 3],
    );
    let mut fingers: Vec<ElasticFinger> = (0..3)
        .map(|_| ElasticFinger {
            position_deg: 0.0,
            n_per_deg,
            force_n: 0.0,
        })
        .collect();
    let dt = 1.0 / RATE_HZ;
    let mut tail = Vec::new();
    let sets = (20.0 * RATE_HZ) as usize;
    for k in 0..sets {
        let set = FusedSet {
            fingers: fingers.iter().map(ElasticFinger::contact).collect(),
            ..FusedSet::default()
        };
        let states: Vec<ServoState> = fingers
            .iter()
            .map(|f| ServoState {
                position_deg: f.position_deg,
                current_ma: SPRING_MA,
                ..ServoState::default()
            })
            .collect();
        let out = ctl.step(k as f64 * dt, Some(&set), &states);
        for (f, g) in fingers.iter_mut().zip(&out.goals) {
            f.step(g, dt);
        }
        if k as f64 >= sets as f64 - 2.0 * RATE_HZ {
            tail.push(fingers[0].force_n);
        }
    }
    tail
}

#[test]
fn a_stiff_contact_is_held_steady_at_its_target() {
    for (n_per_deg, target_n) in [(3.7, 4.0), (10.0, 4.0), (0.5, 1.5)] {
        let tail = held_forces(n_per_deg, target_n);
        let (lo, hi) = tail
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(*y), b.max(*y)));
        assert!(
            hi - lo <= 0.1 * target_n && (lo + hi) / 2.0 > 0.9 * target_n,
            "{n_per_deg} N/deg at {target_n} N: the force ran {lo:.2}..{hi:.2} N"
        );
    }
}
