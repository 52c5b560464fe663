//! The grasp controller against a toy finger: the servo follows its goal at up to 90°/s;
//! past the contact angle the fused force follows `gain × (current − spring current)` with
//! a first-order lag, as a current-capped servo pressing on an object does.

use super::*;
use crate::fusion::{FusedContact, SensorSlip, SlipLoad};

pub(crate) struct ToyFinger {
    pub(crate) position_deg: f64,
    contact_deg: Option<f64>,
    force_n: f64,
}

const SPRING_MA: f64 = 100.0;
const N_PER_MA: f64 = 0.05;

impl ToyFinger {
    pub(crate) fn step(&mut self, goal: &FingerGoal, dt: f64) {
        let limit = self.contact_deg.unwrap_or(f64::INFINITY);
        let max_step = 90.0 * dt;
        let wanted = (goal.position_deg - self.position_deg).clamp(-max_step, max_step);
        self.position_deg = (self.position_deg + wanted).min(limit);
        let pressing = self
            .contact_deg
            .is_some_and(|c| self.position_deg >= c - 1e-9)
            && goal.position_deg > self.position_deg;
        let steady = if pressing {
            N_PER_MA * (goal.goal_current_ma - SPRING_MA).max(0.0)
        } else {
            0.0
        };
        self.force_n += (steady - self.force_n) * (dt / 0.05).min(1.0);
    }

    pub(crate) fn state(&self, goal: &FingerGoal) -> ServoState {
        ServoState {
            position_deg: self.position_deg,
            current_ma: if self.force_n > 0.0 {
                goal.goal_current_ma
            } else {
                SPRING_MA
            },
            ..ServoState::default()
        }
    }

    pub(crate) fn fused(&self) -> FusedContact {
        toy_contact(self.force_n)
    }
}

/// The fused contact of a toy finger pressing with `force_n`.
pub(crate) fn toy_contact(force_n: f64) -> FusedContact {
    FusedContact {
        contact: force_n > 0.01,
        area_mm2: force_n * 20.0,
        max_depth_mm: force_n * 0.1,
        force_n,
        centroid: (force_n > 0.01).then_some((0, 0.0, 0.0)),
        stale: false,
        slip: None,
        slip_load: SlipLoad::default(),
    }
}

/// `contact` slipping as `slip`, as fusion tells it of a one-sensor finger.
pub(crate) fn slipping(contact: &mut FusedContact, slip: SensorSlip) {
    contact.slip = Some(slip);
    contact.slip_load = SlipLoad::default();
    contact.slip_load.add(contact.force_n, &slip);
}

/// The fused set the toy fingers give.
pub(crate) fn toy_set(fingers: &[ToyFinger]) -> FusedSet {
    FusedSet {
        fingers: fingers.iter().map(ToyFinger::fused).collect(),
        ..FusedSet::default()
    }
}

pub(crate) fn request(target_n: f64) -> GraspRequest {
    GraspRequest {
        target_force_n: target_n,
        speed_deg_s: 60.0,
        current_limit_ma: 1000.0,
        fingers: vec![0, 1, 2],
        timeout_s: 30.0,
        auto_target: false,
    }
}

/// Run for `seconds` from the controller's last step on (or from 0); a grasp that ends on
/// the way returns at once, one that had already ended runs on (the hold). Returns the
/// outcome and each step's forces.
fn run(
    ctl: &mut GraspController,
    fingers: &mut [ToyFinger],
    seconds: f64,
    rate_hz: f64,
) -> (Option<GraspOutcome>, Vec<Vec<f64>>) {
    let dt = 1.0 / rate_hz;
    let t0 = ctl.last_s.map_or(0.0, |s| s + dt);
    let was_done = ctl.outcome().is_some();
    let mut forces = Vec::new();
    let mut goals = ctl.goals();
    for k in 0..(seconds * rate_hz) as usize {
        let t = t0 + k as f64 * dt;
        let set = toy_set(fingers);
        let states: Vec<ServoState> = fingers
            .iter()
            .zip(&goals)
            .map(|(f, g)| f.state(g))
            .collect();
        let out = ctl.step(t, Some(&set), &states);
        goals = out.goals.clone();
        for (f, g) in fingers.iter_mut().zip(&goals) {
            f.step(g, dt);
        }
        forces.push(fingers.iter().map(|f| f.force_n).collect());
        if !was_done && out.done.is_some() {
            return (out.done, forces);
        }
    }
    (ctl.outcome().cloned(), forces)
}

pub(crate) fn toy(contact: Option<f64>) -> Vec<ToyFinger> {
    (0..3)
        .map(|_| ToyFinger {
            position_deg: 0.0,
            contact_deg: contact,
            force_n: 0.0,
        })
        .collect()
}

fn controller(target_n: f64) -> GraspController {
    GraspController::new(
        request(target_n),
        Tuning::default(),
        vec![150.0; 3],
        vec![0.0; 3],
    )
}

#[test]
fn closes_on_an_object_and_settles_at_the_target_without_overshoot() {
    let mut ctl = controller(2.0);
    let mut f = toy(Some(60.0));
    let (done, forces) = run(&mut ctl, &mut f, 10.0, 30.0);
    let done = done.expect("finishes");
    assert!(done.grasped, "{done:?}");
    assert_eq!(done.reason, "stable");
    assert!(
        done.status
            .iter()
            .all(|s| *s == FingerStatus::ContactClosing)
    );
    let peak = forces.iter().flatten().copied().fold(0.0, f64::max);
    assert!(peak <= 2.0 * 1.10, "peak {peak} N");
    assert!(forces.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn no_object_closes_fully_and_says_so() {
    let mut ctl = controller(2.0);
    let mut f = toy(None);
    let (done, _) = run(&mut ctl, &mut f, 10.0, 30.0);
    let done = done.expect("finishes");
    assert!(!done.grasped);
    assert_eq!(done.reason, "no_object");
    assert!(done.status.iter().all(|s| *s == FingerStatus::NoObject));
}

#[test]
fn the_same_inputs_give_the_same_outputs() {
    let go = || {
        let mut ctl = controller(1.5);
        let mut f = toy(Some(45.0));
        run(&mut ctl, &mut f, 4.0, 30.0).1
    };
    assert_eq!(go(), go());
}

#[test]
fn force_never_exceeds_what_the_current_cap_allows_even_for_a_huge_target() {
    let mut ctl = controller(1e9);
    let mut f = toy(Some(30.0));
    let (done, forces) = run(&mut ctl, &mut f, 6.0, 30.0);
    // It stalls at the cap, says so, and holds below it instead of straining.
    let done = done.expect("a stall at the cap ends the grasp");
    assert_eq!(done.reason, "force_limited");
    assert!(done.grasped);
    let cap = N_PER_MA * (1000.0 - SPRING_MA);
    assert!(
        forces
            .iter()
            .flatten()
            .all(|v| *v <= cap + 1e-9 && v.is_finite())
    );
    assert!(ctl.goals().iter().all(|g| g.goal_current_ma <= 1000.0));
}

#[test]
fn after_settling_the_force_is_steady_across_rates_and_small_targets() {
    for (target, rate) in [(0.05, 30.0), (2.0, 5.0), (2.0, 120.0), (40.0, 30.0)] {
        let mut ctl = controller(target);
        let mut f = toy(Some(40.0));
        let (done, _) = run(&mut ctl, &mut f, 30.0, rate);
        assert!(
            done.is_some_and(|d| d.grasped),
            "target {target} N at {rate} Hz"
        );
        let (_, tail) = run(&mut ctl, &mut f, 2.0, rate);
        let ys: Vec<f64> = tail.iter().map(|v| v[0]).collect();
        assert_eq!(ys.len(), (2.0 * rate) as usize, "a 2 s tail at {rate} Hz");
        let (lo, hi) = ys
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(*y), b.max(*y)));
        assert!(
            hi - lo <= 0.05 * target + 1e-9,
            "target {target} at {rate} Hz: {lo}..{hi}"
        );
    }
}

#[test]
fn a_stale_finger_holds_and_slip_retightens() {
    let mut ctl = controller(2.0);
    let mut f = toy(Some(50.0));
    let (done, _) = run(&mut ctl, &mut f, 10.0, 30.0);
    assert!(done.is_some_and(|d| d.grasped));
    let before = ctl.goals();
    let stale = FusedSet {
        fingers: vec![
            FusedContact {
                stale: true,
                ..f[0].fused()
            },
            f[1].fused(),
            f[2].fused(),
        ],
        ..FusedSet::default()
    };
    let states: Vec<ServoState> = f.iter().zip(&before).map(|(x, g)| x.state(g)).collect();
    let out = ctl.step(20.0, Some(&stale), &states);
    assert_eq!(
        out.goals[0].position_deg, f[0].position_deg,
        "holds where it is"
    );
    assert_eq!(out.goals[0].goal_current_ma, before[0].goal_current_ma);
    // Slip: the centroid jumps on finger 1.
    let mut moved = f[1].fused();
    moved.centroid = Some((0, 3.0, 0.0));
    let slip = FusedSet {
        fingers: vec![f[0].fused(), moved, f[2].fused()],
        ..FusedSet::default()
    };
    // One set with a shift is not slip yet (a glitch must not squeeze harder)…
    ctl.step(20.1, Some(&slip), &states);
    assert_eq!(ctl.targets_n()[1], 2.0, "{:?}", ctl.targets_n());
    assert_eq!(ctl.phases()[1], Phase::Hold);
    // …the second in a row is.
    ctl.step(20.133, Some(&slip), &states);
    assert!(ctl.targets_n()[1] > 2.0 * 1.1, "{:?}", ctl.targets_n());
    assert_eq!(ctl.phases()[1], Phase::Squeeze);
}

#[test]
fn estop_holds_at_minimum_current_and_release_opens() {
    let mut ctl = controller(2.0);
    let mut f = toy(Some(50.0));
    run(&mut ctl, &mut f, 3.0, 30.0);
    ctl.estop(&[10.0, 20.0, 30.0]);
    let g = ctl.goals();
    assert_eq!(g[1].position_deg, 20.0);
    assert!(
        g.iter()
            .all(|g| g.goal_current_ma == Tuning::default().min_current_ma)
    );
    assert!(ctl.phases().iter().all(|p| *p == Phase::Fault));
    let mut ctl = controller(2.0);
    run(&mut ctl, &mut f, 3.0, 30.0);
    ctl.release();
    let states: Vec<ServoState> = vec![
        ServoState {
            position_deg: 40.0,
            ..ServoState::default()
        };
        3
    ];
    let set = FusedSet {
        fingers: vec![FusedContact::default(); 3],
        ..FusedSet::default()
    };
    let out = ctl.step(10.0, Some(&set), &states);
    assert!(out.goals.iter().all(|g| g.position_deg == 0.0));
}

#[test]
fn a_one_set_outlier_does_not_move_the_finger() {
    let mut ctl = controller(2.0);
    let mut f = toy(Some(50.0));
    run(&mut ctl, &mut f, 10.0, 30.0);
    let states: Vec<ServoState> = f
        .iter()
        .zip(&ctl.goals())
        .map(|(x, g)| x.state(g))
        .collect();
    let normal = toy_set(&f);
    let mut spike = normal.clone();
    spike.fingers[0].force_n *= 10.0;
    let mut a = ctl.clone();
    let mut b = ctl.clone();
    let next_s = ctl.last_s.expect("stepped") + 1.0 / 30.0;
    let quiet = a.step(next_s, Some(&normal), &states);
    let glitch = b.step(next_s, Some(&spike), &states);
    assert_eq!(quiet.goals, glitch.goals);
    assert_eq!(a.forces_n(), b.forces_n());
}

#[test]
fn at_5_hz_a_one_set_outlier_backs_a_finger_off_by_at_most_the_whole_target() {
    // At 5 Hz the median of three would delay the force by a whole set, so it is skipped;
    // an outlier then reaches the loop, but only as an excess of one target.
    let target = 2.0;
    let mut ctl = controller(target);
    let mut f = toy(Some(50.0));
    let (done, _) = run(&mut ctl, &mut f, 30.0, 5.0);
    assert!(done.is_some_and(|d| d.grasped));
    let states: Vec<ServoState> = f
        .iter()
        .zip(&ctl.goals())
        .map(|(x, g)| x.state(g))
        .collect();
    let mut spike = toy_set(&f);
    spike.fingers[0].force_n *= 10.0;
    let before = ctl.goals()[0];
    let out = ctl.step(ctl.last_s.expect("stepped") + 0.2, Some(&spike), &states);
    let tuning = Tuning::default();
    let back_deg = f[0].position_deg - out.goals[0].position_deg;
    assert!(
        back_deg <= tuning.squeeze_deg_per_n * target + 1e-9,
        "backed off {back_deg}°"
    );
    let drop_ma = before.goal_current_ma - out.goals[0].goal_current_ma;
    assert!(
        drop_ma <= tuning.kp_ma_per_n * target + 1e-9,
        "current fell {drop_ma} mA"
    );
}

#[test]
fn a_contact_that_vanishes_before_the_squeeze_was_not_one() {
    let mut ctl = controller(2.0);
    let f = toy(None);
    let states: Vec<ServoState> = f
        .iter()
        .map(|x| ServoState {
            position_deg: x.position_deg,
            ..ServoState::default()
        })
        .collect();
    let mut glitch = toy_set(&f);
    glitch.fingers[0].contact = true;
    ctl.step(0.0, Some(&toy_set(&f)), &states);
    ctl.step(0.033, Some(&glitch), &states);
    assert_eq!(ctl.phases()[0], Phase::Contact);
    ctl.step(0.066, Some(&toy_set(&f)), &states);
    assert_eq!(ctl.phases()[0], Phase::Approach, "back to approaching");
    // Long after, it has not squeezed blindly: the cap is still the approach cap.
    for k in 3..30 {
        ctl.step(k as f64 * 0.033, Some(&toy_set(&f)), &states);
    }
    assert_eq!(ctl.phases()[0], Phase::Approach);
    assert!(ctl.goals()[0].goal_current_ma <= Tuning::default().approach_current_ma);
}

#[test]
fn first_contact_presses_on_with_half_the_approach_margin() {
    let t = Tuning::default();
    let mut ctl = controller(2.0);
    let mut f = toy(Some(20.0));
    let mut approach_ma = 0.0;
    let mut contact_ma = None;
    for _ in 0..300 {
        let before = ctl.phases()[0];
        run(&mut ctl, &mut f, 1.0 / 30.0, 30.0);
        match (before, ctl.phases()[0]) {
            (_, Phase::Approach) => approach_ma = ctl.goals()[0].goal_current_ma,
            (Phase::Approach, Phase::Contact) => {
                contact_ma = Some(ctl.goals()[0].goal_current_ma);
                break;
            }
            _ => {}
        }
    }
    let contact_ma = contact_ma.expect("contact within 10 s");
    // The approach learnt the springs' 100 mA and added the whole margin…
    assert!(
        (approach_ma - (SPRING_MA + t.approach_margin_ma)).abs() < 2.0,
        "{approach_ma}"
    );
    // …and the contact keeps half of it.
    let expected = SPRING_MA + t.approach_margin_ma * t.contact_margin_share;
    assert!(
        (contact_ma - expected).abs() < 2.0,
        "{contact_ma} vs {expected}"
    );
}

mod reflex;
mod stiff;
