//! The slip reflex in the loop: the toy fingers hold an object that a load pulls along the
//! pads, and each contact's slip is what Cattaneo–Mindlin gives for the load's share of the
//! grip's friction (stick ratio `(1 − Q/μP)^(1/3)`, gross at `Q ≥ μP`).

use super::*;
use crate::fusion::{SensorSlip, SlipState};

const FRICTION: f64 = 0.5;
const RATE_HZ: f64 = 60.0;

/// The set the toy fingers give under a pull of `load_n`: every contact slips alike.
fn loaded_set(fingers: &[ToyFinger], load_n: f64) -> FusedSet {
    let grip_n: f64 = fingers.iter().map(|f| f.force_n).sum();
    let used = if grip_n > 0.0 {
        load_n / (FRICTION * grip_n)
    } else {
        1.0
    };
    // The gel shears with each contact's share of the pull (a toy compliance, mm per N).
    let slip = SensorSlip {
        shear_mm: [0.05 * load_n / fingers.len().max(1) as f64, 0.0],
        stick_ratio: (1.0 - used).max(0.0).cbrt(),
        state: if used >= 1.0 {
            SlipState::Gross
        } else if used > 1.0 - 0.9f64.powi(3) {
            SlipState::Incipient
        } else {
            SlipState::None
        },
    };
    let mut set = toy_set(fingers);
    for c in &mut set.fingers {
        slipping(c, slip);
    }
    set
}

/// What a loaded run saw: the most the load used of the grip's friction, and the last
/// step's total grip, N.
struct Loaded {
    most_used: f64,
    grip_n: f64,
}

/// Run on from the controller's last step for `seconds` under the pull `load_n(t)` (t from
/// the run's start), counting from `settle_s` on.
fn run_loaded(
    ctl: &mut GraspController,
    fingers: &mut [ToyFinger],
    seconds: f64,
    settle_s: f64,
    load_n: impl Fn(f64) -> f64,
) -> Loaded {
    let dt = 1.0 / RATE_HZ;
    let t0 = ctl.last_s.map_or(0.0, |s| s + dt);
    let mut goals = ctl.goals();
    let mut seen = Loaded {
        most_used: 0.0,
        grip_n: 0.0,
    };
    for k in 0..(seconds * RATE_HZ) as usize {
        let t = k as f64 * dt;
        let set = loaded_set(fingers, load_n(t));
        let states: Vec<ServoState> = fingers
            .iter()
            .zip(&goals)
            .map(|(f, g)| f.state(g))
            .collect();
        goals = ctl.step(t0 + t, Some(&set), &states).goals;
        for (f, g) in fingers.iter_mut().zip(&goals) {
            f.step(g, dt);
        }
        seen.grip_n = fingers.iter().map(|f| f.force_n).sum();
        if t >= settle_s {
            seen.most_used = seen.most_used.max(load_n(t) / (FRICTION * seen.grip_n));
        }
    }
    seen
}

/// A controller at `target_n` settled on the toy object, no load.
fn held(target_n: f64, tuning: Tuning) -> (GraspController, Vec<ToyFinger>) {
    let mut ctl = GraspController::new(request(target_n), tuning, vec![150.0; 3], vec![0.0; 3]);
    let mut f = toy(Some(60.0));
    let out = run_loaded(&mut ctl, &mut f, 10.0, 0.0, |_| 0.0);
    assert!(ctl.outcome().is_some_and(|o| o.grasped), "{:?}", out.grip_n);
    (ctl, f)
}

#[test]
fn a_growing_load_is_held_at_little_more_than_the_least_grip() {
    let (mut ctl, mut f) = held(1.0, Tuning::default());
    let max_n = Tuning::default().grasp.max_force_n;
    // A ramp to 80% of what the most force holds, in 6 s, then held.
    let top_n = 0.8 * FRICTION * 3.0 * max_n;
    let seen = run_loaded(&mut ctl, &mut f, 12.0, 0.0, |t| top_n * (t / 6.0).min(1.0));
    assert!(
        seen.most_used < 1.0,
        "the load slid the object: {:.2}",
        seen.most_used
    );
    let least_n = top_n / FRICTION;
    assert!(
        seen.grip_n >= least_n && seen.grip_n <= 1.5 * least_n,
        "grip {:.2} N, least {least_n:.2} N",
        seen.grip_n
    );
    assert!(
        ctl.targets_n().iter().all(|t| *t <= max_n + 1e-9),
        "{:?}",
        ctl.targets_n()
    );
    assert_eq!(ctl.outcome().map(|o| o.reason), Some(GraspReason::Stable));
}

#[test]
fn a_load_that_goes_relaxes_slowly_to_the_requested_force() {
    let (mut ctl, mut f) = held(1.0, Tuning::default());
    let pull = |t: f64| {
        if t < 3.0 {
            4.0 * (t / 1.5).min(1.0)
        } else {
            0.0
        }
    };
    run_loaded(&mut ctl, &mut f, 3.0, 0.0, pull);
    let raised = ctl.targets_n();
    assert!(raised.iter().all(|t| *t > 2.0), "{raised:?}");
    // Unloaded for 1 s: down by at most a tenth of the rate.
    run_loaded(&mut ctl, &mut f, 1.0, 0.0, |_| 0.0);
    let rate = Tuning::default().grasp.reflex_rate_n_s;
    for (now, before) in ctl.targets_n().iter().zip(&raised) {
        assert!(
            *now < *before && before - now <= 0.1 * rate * 1.0 + 1e-9,
            "{now} from {before}"
        );
    }
    run_loaded(&mut ctl, &mut f, 20.0, 0.0, |_| 0.0);
    assert!(
        ctl.targets_n().iter().all(|t| (*t - 1.0).abs() < 1e-9),
        "{:?}",
        ctl.targets_n()
    );
}

#[test]
fn a_load_beyond_the_most_force_ends_slipping_with_the_fingers_holding() {
    let (mut ctl, mut f) = held(1.0, Tuning::default());
    let max_n = Tuning::default().grasp.max_force_n;
    let beyond_n = 1.5 * FRICTION * 3.0 * max_n;
    run_loaded(&mut ctl, &mut f, 6.0, 0.0, |t| {
        beyond_n * (t / 2.0).min(1.0)
    });
    let outcome = ctl.outcome().expect("ended");
    assert_eq!(outcome.reason, GraspReason::Slipping);
    assert!(!outcome.grasped);
    assert_eq!(outcome.reason.to_string(), "slipping");
    let goals = ctl.goals();
    for (finger, goal) in f.iter().zip(&goals) {
        assert_eq!(goal.position_deg, finger.position_deg, "holds where it is");
    }
    // Held on: neither squeezing on nor letting go.
    let currents: Vec<f64> = goals.iter().map(|g| g.goal_current_ma).collect();
    run_loaded(&mut ctl, &mut f, 1.0, 0.0, |_| beyond_n);
    let after: Vec<f64> = ctl.goals().iter().map(|g| g.goal_current_ma).collect();
    assert_eq!(currents, after);
    assert!(ctl.targets_n().iter().all(|t| *t <= max_n + 1e-9));
}

/// The rubber duck after its table drops (docs/control.md): besides each finger's
/// load-bearing contact, which sticks, finger 1 touches with a second, light contact that
/// carries all its friction can and so slides whole, while the object holds. The grasp
/// holds by the load its contacts carry: it neither gives up nor squeezes to the most.
#[test]
fn a_light_contact_sliding_whole_beside_ones_that_stick_neither_squeezes_nor_gives_up() {
    let (mut ctl, mut f) = held(1.5, Tuning::default());
    let dt = 1.0 / RATE_HZ;
    let t0 = ctl.last_s.expect("stepped") + dt;
    let mut goals = ctl.goals();
    let sticks = SensorSlip {
        shear_mm: [0.1, 0.0],
        stick_ratio: 0.92,
        state: SlipState::None,
    };
    let slides = SensorSlip {
        shear_mm: [0.05, 0.0],
        stick_ratio: 0.18,
        state: SlipState::Gross,
    };
    for k in 0..(10.0 * RATE_HZ) as usize {
        let mut set = toy_set(&f);
        for c in &mut set.fingers {
            slipping(c, sticks);
        }
        // The light contact: a fifth of the finger's force, sliding whole.
        let light_n = 0.2 * set.fingers[0].force_n;
        set.fingers[0].slip = Some(slides);
        set.fingers[0].slip_load.add(light_n, &slides);
        let states: Vec<ServoState> = f.iter().zip(&goals).map(|(x, g)| x.state(g)).collect();
        goals = ctl.step(t0 + k as f64 * dt, Some(&set), &states).goals;
        for (x, g) in f.iter_mut().zip(&goals) {
            x.step(g, dt);
        }
    }
    let outcome = ctl.outcome().expect("ended");
    assert!(outcome.grasped, "{outcome:?}");
    assert_ne!(outcome.reason, GraspReason::Slipping);
    let targets = ctl.targets_n();
    assert!(targets.iter().all(|t| *t <= 1.5 + 1e-9), "{targets:?}");
}

#[test]
fn with_the_reflex_off_the_target_stays() {
    let mut tuning = Tuning::default();
    tuning.grasp.reflex = false;
    let (mut ctl, mut f) = held(1.0, tuning);
    run_loaded(&mut ctl, &mut f, 3.0, 0.0, |t| 1.2 * (t / 1.0).min(1.0));
    assert_eq!(ctl.targets_n(), vec![1.0; 3]);
}

#[test]
fn a_finger_outside_the_grasp_does_not_trigger_its_reflex() {
    // One finger's controller (a task stage's), the other two moved on purpose.
    let mut one = request(1.0);
    one.fingers = vec![0];
    let mut ctl = GraspController::new(one, Tuning::default(), vec![150.0; 3], vec![0.0; 3]);
    let mut f = toy(Some(60.0));
    run(&mut ctl, &mut f, 10.0, RATE_HZ);
    assert_eq!(ctl.phases()[0], Phase::Hold);
    let gross = SensorSlip {
        shear_mm: [0.5, 0.0],
        stick_ratio: 0.0,
        state: SlipState::Gross,
    };
    let states: Vec<ServoState> = f
        .iter()
        .zip(ctl.goals().iter())
        .map(|(x, g)| x.state(g))
        .collect();
    let t0 = ctl.last_s.unwrap_or(0.0);
    for k in 1..=30 {
        let mut set = toy_set(&f);
        slipping(&mut set.fingers[1], gross);
        slipping(&mut set.fingers[2], gross);
        ctl.step(t0 + k as f64 / RATE_HZ, Some(&set), &states);
    }
    assert_eq!(ctl.targets_n()[0], 1.0);
}

#[test]
fn an_auto_grasp_closes_to_the_preload_and_settles_at_the_least_that_holds_with_the_margin() {
    let mut auto = request(f64::NAN); // not used
    auto.auto_target = true;
    let mut ctl = GraspController::new(auto, Tuning::default(), vec![150.0; 3], vec![0.0; 3]);
    let mut f = toy(Some(60.0));
    let preload = Tuning::default().grasp.preload_n;
    // Unloaded, it holds at the preload.
    run_loaded(&mut ctl, &mut f, 10.0, 0.0, |_| 0.0);
    let idle = ctl.outcome().expect("ended").clone();
    assert_eq!(idle.reason, GraspReason::Stable);
    assert_eq!(idle.settled_force_n, Some(preload));
    assert_eq!(ctl.targets_n(), vec![preload; 3]);
    // Loaded from the start (1 N at μ 0.5: 2 N of grip holds, 0.67 N a finger), it
    // settles the margin above that (the toy's stick ratio is exact), and says so once its
    // reflex has stopped raising it.
    let mut auto = request(f64::NAN);
    auto.auto_target = true;
    let mut ctl = GraspController::new(auto, Tuning::default(), vec![150.0; 3], vec![0.0; 3]);
    let mut f = toy(Some(60.0));
    let seen = run_loaded(&mut ctl, &mut f, 15.0, 8.0, |_| 1.0);
    let outcome = ctl.outcome().expect("ended");
    assert_eq!(outcome.reason, GraspReason::Stable, "{outcome:?}");
    let settled = outcome
        .settled_force_n
        .expect("an auto grasp's settled force");
    let least = 1.0 / FRICTION / 3.0;
    let with_margin = (1.0 + Tuning::default().grasp.slip_margin) * least;
    assert!(
        settled > least && (settled / with_margin - 1.0).abs() < 0.1,
        "settled {settled:.3}, least {least:.3}, with the margin {with_margin:.3}"
    );
    assert!(seen.most_used < 1.0, "{:.2}", seen.most_used);
    // A fixed target reports none.
    let (fixed, _) = held(1.0, Tuning::default());
    assert_eq!(fixed.outcome().and_then(|o| o.settled_force_n), None);
}

/// The object slides out faster than the reflex can tighten: once the fingers feel slip
/// and then nothing for three sets, the grasp ends `slipping` with every finger holding
/// where it is, never closing on toward its target on nothing.
#[test]
fn an_object_lost_to_a_slide_ends_slipping_without_squeezing_on_nothing() {
    let (mut ctl, mut f) = held(1.0, Tuning::default());
    let dt = 1.0 / RATE_HZ;
    let t0 = ctl.last_s.expect("stepped") + dt;
    let mut goals = ctl.goals();
    // A load the grip feels as incipient slip, for a few sets.
    let load_n = 0.6 * FRICTION * 3.0;
    for k in 0..5 {
        let set = loaded_set(&f, load_n);
        assert!(
            set.fingers[0]
                .slip
                .is_some_and(|s| s.state == SlipState::Incipient)
        );
        let states: Vec<ServoState> = f.iter().zip(&goals).map(|(x, g)| x.state(g)).collect();
        goals = ctl.step(t0 + k as f64 * dt, Some(&set), &states).goals;
    }
    assert!(ctl.outcome().is_some_and(|o| o.grasped));
    // Gone: no contact on any finger.
    let mut gone = toy_set(&f);
    for c in &mut gone.fingers {
        *c = FusedContact::default();
    }
    for k in 5..9 {
        let states: Vec<ServoState> = f.iter().zip(&goals).map(|(x, g)| x.state(g)).collect();
        goals = ctl.step(t0 + k as f64 * dt, Some(&gone), &states).goals;
        for (x, g) in f.iter_mut().zip(&goals) {
            x.step(g, dt);
        }
    }
    let outcome = ctl.outcome().expect("ended");
    assert_eq!(outcome.reason, GraspReason::Slipping, "{outcome:?}");
    for (finger, goal) in f.iter().zip(ctl.goals()) {
        assert_eq!(goal.position_deg, finger.position_deg, "holds where it is");
    }
    // Without slip felt first, losing the contact is not a slide (the area rule's case).
    let (mut calm, mut g) = held(1.0, Tuning::default());
    let t1 = calm.last_s.expect("stepped") + dt;
    let mut goals = calm.goals();
    for k in 0..6 {
        let states: Vec<ServoState> = g.iter().zip(&goals).map(|(x, g)| x.state(g)).collect();
        goals = calm.step(t1 + k as f64 * dt, Some(&gone), &states).goals;
        for (x, goal) in g.iter_mut().zip(&goals) {
            x.step(goal, dt);
        }
    }
    assert_ne!(
        calm.outcome().map(|o| o.reason),
        Some(GraspReason::Slipping)
    );
}
