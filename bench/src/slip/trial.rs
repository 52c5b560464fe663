//! One `bench slip` trial: the object gripped, settled at 1.5× the least grip that holds
//! its weight, then pulled along its `slip_dir` by a ramp that reaches the grip's holding
//! limit in the trial's load time, set after set on the virtual clock until it slides. Each
//! set is rendered by the simulator's cameras from the world (markers moved by the gel's
//! shear, noise, JPEG) and read by the run's pipelines; the world gives the truth.

use anyhow::Context;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::fusion::{SlipState, weight_force_n};
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::runtime::slip_tally::FALSE_ALARM_STICK_RATIO;
use gelgrip_plugins::contact::ContactSummary;
use gelgrip_plugins::pipeline::{Needs, PipelineError, SensorPipeline, process_set};
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::load::{LoadProfile, LoadSpec};
use gelgrip_sim::scene_frames::SceneFrames;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::world::{SharedWorld, World};
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// The grip a trial settles at, as a multiple of the least that holds the object's weight.
pub const GRIP_MARGIN: f64 = 1.5;
/// Sets read before the load begins (their detections count as false alarms too), s.
const BEFORE_LOAD_S: f64 = 0.3;
/// Sets read after gross slip, so that a late detection is still seen.
const SETS_AFTER_GROSS: usize = 3;
/// Settling: each candidate current closes the fingers from open and holds until the
/// grip's friction changes by less than this share over a check of this long, s (at most
/// for this long, s); the current is searched at most this many times between 1 mA and
/// the limit.
const SETTLED_CHANGE: f64 = 0.002;
const SETTLE_CHECK_S: f64 = 0.25;
const SETTLE_MAX_S: f64 = 30.0;
const SETTLE_SEARCHES: usize = 16;
/// The grip settles within this share above its aim.
const SETTLE_TOLERANCE: f64 = 0.03;
/// A finger whose motor turns slower than this has stopped, rpm.
const STILL_RPM: f64 = 0.05;

/// An object held and settled ([`hold`]).
#[derive(Debug, Clone)]
pub struct Held {
    /// The world, its scene as [`held_scene`] makes it.
    pub world: World,
    /// When the grip had settled, µs.
    pub settled_us: u64,
    /// The fingers' current, mA.
    pub current_ma: f64,
}

/// What one trial is.
#[derive(Debug, Clone)]
pub struct TrialSpec<'a> {
    /// The object held.
    pub held: &'a Held,
    /// Seconds for the ramp to reach the holding limit.
    pub load_time_s: f64,
    /// Its number in the sweep's cell, from 0.
    pub trial: usize,
    /// Its simulator seed (camera units and noise), and the load's phase against the sets.
    pub seed: u64,
}

/// One trial as `--json` prints it. Times are seconds since the load began.
#[derive(Debug, Clone, Serialize)]
pub struct SlipRow {
    /// The scene's object.
    pub object: String,
    /// Its friction coefficient μ in this trial.
    pub friction: f64,
    /// Seconds for the ramp to reach the holding limit.
    pub load_time_s: f64,
    /// The trial's number in its cell, from 0.
    pub trial: usize,
    /// Its simulator seed.
    pub seed: u64,
    /// The grip's total normal force when the load began, N.
    pub grip_n: f64,
    /// The pull it holds then (μP less what the normals push along `slip_dir`), N.
    pub holding_limit_n: f64,
    /// The truth: a contact's stick ratio first below 0.9.
    pub t_incipient_s: Option<f64>,
    /// The truth: the object first 0.1 mm along the pads.
    pub t_gross_s: Option<f64>,
    /// The first set a sensor read incipient or gross slip (capture time).
    pub t_detect_s: Option<f64>,
    /// Sets from the detecting set to the first set at or after gross slip.
    pub lead_sets: Option<i64>,
    /// Sensor readings of slip while that sensor's contacts all stuck above 0.95.
    pub false_alarms: u32,
    /// The least true stick ratio when slip was detected.
    pub true_stick_ratio_at_detect: Option<f64>,
    /// Sets read.
    pub sets: usize,
    /// The bus's set period, ms.
    pub set_period_ms: f64,
    /// The slip reflex held the object (`--reflex on`): the grasp controller in the loop.
    pub reflex: bool,
    /// The object's total motion against the fingers since the load began, mm.
    pub motion_mm: f64,
    /// The object slid out of the grasp: out of every contact, or
    /// [`super::reflex::DROP_MM`] along the pads.
    pub dropped: bool,
    /// The true total normal force of the contacts at the end, N.
    pub final_grip_n: f64,
    /// The part of `final_grip_n` on the palm's sensor, N: what the placement presses,
    /// which the fingers' grip does not set.
    pub final_palm_n: f64,
    /// The least total normal force that would have held the final load: the pull at the
    /// last set, over μ, N.
    pub least_grip_n: f64,
}

/// What a trial's row says of its start.
pub(super) struct TrialStart {
    /// The scene's object and its friction μ.
    pub(super) object: String,
    pub(super) friction: f64,
    /// The grip's total normal force and its μP when the load began, N.
    pub(super) grip_n: f64,
    pub(super) holding_limit_n: f64,
    /// When the load began, µs, and the set period, µs.
    pub(super) load_start_us: u64,
    pub(super) set_period_us: u64,
}

impl TrialStart {
    /// The row of a trial that read `sets` sets, tallied in `tally`, its world `w` at the
    /// end and the pull then `pull_n`; `reflex`: the controller held the object.
    pub(super) fn row(
        self,
        spec: &TrialSpec,
        w: &World,
        tally: &Tally,
        sets: usize,
        pull_n: f64,
        reflex: bool,
    ) -> SlipRow {
        let truth = *w.slip_truth();
        let load_s = self.load_start_us as f64 / 1e6;
        SlipRow {
            object: self.object,
            friction: self.friction,
            load_time_s: spec.load_time_s,
            trial: spec.trial,
            seed: spec.seed,
            grip_n: self.grip_n,
            holding_limit_n: self.holding_limit_n,
            t_incipient_s: truth.incipient_s.map(|t| t - load_s),
            t_gross_s: truth.gross_s.map(|t| t - load_s),
            t_detect_s: tally.detect.map(|d| d.1),
            lead_sets: tally
                .detect
                .zip(tally.gross_set)
                .map(|(d, g)| g as i64 - d.0 as i64),
            false_alarms: tally.false_alarms,
            true_stick_ratio_at_detect: tally.detect.map(|d| d.2),
            sets,
            set_period_ms: self.set_period_us as f64 / 1e3,
            reflex,
            motion_mm: truth.motion_mm,
            dropped: w.object().is_some_and(|o| o.dropped)
                || w.grip_n() <= 0.0
                || truth.motion_mm >= super::reflex::DROP_MM,
            final_grip_n: w.grip_n(),
            final_palm_n: w.palm_grip_n(),
            least_grip_n: pull_n / self.friction,
        }
    }
}

/// One set of a trial, for the plot.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct TraceSet {
    /// Capture time since the load began, s.
    pub t_s: f64,
    /// The pull, N.
    pub load_n: f64,
    /// The least true stick ratio over the loaded contacts (1 unloaded).
    pub true_stick_ratio: f64,
    /// The least estimated stick ratio over the sensors that read one.
    pub estimated_stick_ratio: Option<f64>,
    /// Whether a sensor read slip.
    pub detected: bool,
}

/// What a trial runs on.
pub struct Rigging<'a> {
    /// The run's configuration: the hand, its servos and the `[grasp]` section.
    pub config: &'a AppConfig,
    /// The simulator's settings, with the trial's seed.
    pub sim: &'a SimConfig,
    /// The run's pipelines for that seed, freshly referenced.
    pub pipes: &'a mut [SensorPipeline],
    /// The bus's set period, µs.
    pub set_period_us: u64,
}

/// `scene`'s world with the fingers closed on it from open with `current_ma`, settled;
/// and the time reached, µs.
fn closed_world(layout: &HandLayout, scene: &SceneSpec, current_ma: f64) -> (World, u64) {
    let mut world = World::new(layout, Some(scene.clone()));
    world.advance_to(0);
    world.close_fingers(current_ma);
    let (mut t_us, mut last) = (0u64, f64::NAN);
    let check_us = (SETTLE_CHECK_S * 1e6) as u64;
    while t_us < (SETTLE_MAX_S * 1e6) as u64 {
        t_us += check_us;
        world.advance_to(t_us);
        let friction = world.grip_loads_n().0;
        let still = (0..world.fingers())
            .filter_map(|f| world.reading(f))
            .all(|r| r.velocity_rpm.abs() < STILL_RPM);
        // Settled on the object, or stopped short of it (too weak to close the fingers).
        let steady = (friction - last).abs() <= SETTLED_CHANGE * friction;
        if still && (friction > 0.0 && steady || friction == 0.0 && last == 0.0) {
            break;
        }
        last = friction;
    }
    (world, t_us)
}

/// `scene` as a trial holds it: the fixture keeps the weight, and the load will balance
/// the grip's own push along `slip_dir`, so that the contacts carry the ramp alone, from 0
/// to μP.
pub fn held_scene(scene: &SceneSpec, friction: f64) -> SceneSpec {
    let mut scene = scene.clone();
    scene.release_after_s = None;
    scene.object.load = None;
    scene.object.friction = friction;
    scene
}

/// What the grip of `scene`'s object aims to carry: 1.5× its weight, N.
pub fn grip_aim_n(scene: &SceneSpec) -> f64 {
    GRIP_MARGIN * weight_force_n(scene.object.mass_kg * 1e3)
}

/// The current whose grip's friction reaches `aim_n` on `scene` within
/// [`SETTLE_TOLERANCE`] above it (the most current when none reaches it), mA: bisection on
/// the current's logarithm until the fingers touch at the low end, then false position
/// (Illinois) on the friction. Each candidate
/// closes from open, so that the grip does not depend on the path to it.
pub fn hold(layout: &HandLayout, scene: &SceneSpec, aim_n: f64, max_current_ma: f64) -> Held {
    let held = |log_ma: f64| {
        let (world, settled_us) = closed_world(layout, scene, log_ma.exp());
        Held {
            world,
            settled_us,
            current_ma: log_ma.exp(),
        }
    };
    let miss = |h: &Held| h.world.grip_loads_n().0 - aim_n;
    let (mut lo, mut hi) = (0.0f64, max_current_ma.max(1.0).ln());
    let mut best = held(hi);
    let (mut f_lo, mut f_hi) = (-aim_n, miss(&best));
    if f_hi < 0.0 {
        return best;
    }
    let mut side = 0i8;
    for _ in 0..SETTLE_SEARCHES {
        // Bisect while the low end does not touch (its friction is flat at 0 there).
        let x = if f_hi > f_lo && f_lo > -aim_n {
            (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        } else {
            0.5 * (lo + hi)
        };
        let candidate = held(x);
        let f = miss(&candidate);
        if (0.0..=SETTLE_TOLERANCE * aim_n).contains(&f) {
            return candidate;
        }
        if f < 0.0 {
            (lo, f_lo) = (x, f);
            // Illinois: halve the end that stayed twice, so that it moves.
            if side == -1 {
                f_hi *= 0.5;
            }
            side = -1;
        } else {
            (hi, f_hi, best) = (x, f, candidate);
            if side == 1 {
                f_lo *= 0.5;
            }
            side = 1;
        }
    }
    best
}

/// Each sensor's reading of slip in a set.
pub(super) fn states(
    results: &[Result<ContactSummary, PipelineError>],
) -> Vec<Option<(SlipState, f64)>> {
    results
        .iter()
        .map(|r| {
            let e = r.as_ref().ok()?.shear?;
            Some((e.state, e.stick_ratio))
        })
        .collect()
}

/// What the sets of a trial showed so far.
#[derive(Debug, Default)]
pub(super) struct Tally {
    /// The detecting set: its number, time since the load began (s) and the least true
    /// stick ratio then.
    pub(super) detect: Option<(usize, f64, f64)>,
    /// The first set at or after gross slip.
    pub(super) gross_set: Option<usize>,
    /// Readings of slip while that sensor's contacts all stuck.
    pub(super) false_alarms: u32,
    /// Every set, for the plot.
    pub(super) trace: Vec<TraceSet>,
}

/// Run one trial.
pub fn run(rig: &mut Rigging<'_>, spec: &TrialSpec) -> anyhow::Result<(SlipRow, Vec<TraceSet>)> {
    let mut world = spec.held.world.clone();
    let settled_us = spec.held.settled_us;
    let (object, friction) = world
        .object()
        .map(|o| (o.spec().name.clone(), o.spec().friction))
        .context("the scene has no object")?;
    let grip_n = world.grip_n();
    let (limit_n, push_n) = world.grip_loads_n();
    anyhow::ensure!(
        limit_n > 0.0,
        "{object}: the fingers do not grip it (holding limit 0 N at {:.0} mA)",
        spec.held.current_ma
    );
    let period = rig.set_period_us;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(spec.seed);
    let phase_us = rng.random_range(0..period.max(1));
    let load_start_us = settled_us + (BEFORE_LOAD_S * 1e6) as u64 + phase_us;
    let rate = limit_n / spec.load_time_s;
    world.set_object_load(Some(LoadSpec {
        profile: LoadProfile::Ramp {
            rate_n_per_s: rate,
            max_n: None,
        },
        start_s: load_start_us as f64 / 1e6,
        offset_n: -push_n,
    }));
    let world = world.into_shared();
    let mut frames = SceneFrames::new(world.clone(), &rig.config.layout, rig.sim)?;
    let end_us = load_start_us + ((2.0 * spec.load_time_s + 1.0) * 1e6) as u64;
    let since_load = |t_us: u64| (t_us as f64 - load_start_us as f64) / 1e6;
    let mut tally = Tally::default();
    let mut results: Vec<Result<ContactSummary, PipelineError>> = (0..rig.pipes.len())
        .map(|_| Err(PipelineError::NoReference))
        .collect();
    let mut nth = 0usize;
    loop {
        let now_us = settled_us + nth as u64 * period;
        let jpegs = frames.capture(now_us, nth as u64)?;
        let views: Vec<&[u8]> = jpegs.iter().map(|j| &j[..]).collect();
        process_set(rig.pipes, &views, Needs::DEPTH, &mut results);
        let read = states(&results);
        let t_s = since_load(now_us);
        observe(&world, &read, t_s, rate, nth, &mut tally)?;
        nth += 1;
        let done = tally.gross_set.is_some_and(|g| nth >= g + SETS_AFTER_GROSS);
        if done || now_us >= end_us {
            break;
        }
    }
    let w = world
        .lock()
        .map_err(|_| anyhow::anyhow!("the world was poisoned"))?;
    // The pull at the last set read.
    let pull_n = rate * since_load(settled_us + (nth.max(1) as u64 - 1) * period).max(0.0);
    let start = TrialStart {
        object,
        friction,
        grip_n,
        holding_limit_n: limit_n,
        load_start_us,
        set_period_us: period,
    };
    let row = start.row(spec, &w, &tally, nth, pull_n, false);
    Ok((row, tally.trace))
}

/// Read the truth of set `nth` at `t_s` and tally its sensors' readings `read`.
pub(super) fn observe(
    world: &SharedWorld,
    read: &[Option<(SlipState, f64)>],
    t_s: f64,
    rate_n_per_s: f64,
    nth: usize,
    tally: &mut Tally,
) -> anyhow::Result<()> {
    let w = world
        .lock()
        .map_err(|_| anyhow::anyhow!("the world was poisoned"))
        .context("reading the truth")?;
    let sticks: Vec<f64> = (0..read.len()).map(|s| w.stick_ratio(s)).collect();
    let least_true = sticks.iter().copied().fold(1.0, f64::min);
    let slipping = |r: &Option<(SlipState, f64)>| r.is_some_and(|(s, _)| s >= SlipState::Incipient);
    let detected = read.iter().any(slipping);
    tally.false_alarms += read
        .iter()
        .zip(&sticks)
        .filter(|(r, stick)| slipping(r) && **stick > FALSE_ALARM_STICK_RATIO)
        .count() as u32;
    if detected && tally.detect.is_none() {
        tally.detect = Some((nth, t_s, least_true));
    }
    if tally.gross_set.is_none() && w.slip_truth().gross_s.is_some() {
        tally.gross_set = Some(nth);
    }
    tally.trace.push(TraceSet {
        t_s,
        load_n: (rate_n_per_s * t_s).max(0.0),
        true_stick_ratio: least_true,
        estimated_stick_ratio: read.iter().flatten().map(|r| r.1).reduce(f64::min),
        detected,
    });
    Ok(())
}
