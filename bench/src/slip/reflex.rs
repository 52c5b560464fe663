//! One `bench slip --reflex on` trial: the grasp controller closes the fingers from open on
//! the object (held in place by the scene's fixture) as a grasp that finds its own force
//! (`auto`: to `[grasp] preload_n`), and once it holds, the object is pulled
//! along its `slip_dir` by the trial's ramp, which stops at 80% of what `[grasp]
//! max_force_n` can hold (`μ × fingers × max_force_n`). Each set is rendered from the world
//! and read by the run's pipelines, fused, and stepped through the controller, whose goals
//! reach the simulated servos through the simulator's servo bus: the code path of a run,
//! on the virtual clock. The world gives the truth: the object's motion against the
//! fingers, whether it was dropped, the grip at the end and the least grip that would have
//! held the final load.

use anyhow::Context;
use gelgrip_controller::actuator::ServoBus;
use gelgrip_controller::clock::{Clock, VirtualClock};
use gelgrip_controller::fusion::{FusedSet, fuse};
use gelgrip_controller::grasp::{GraspController, GraspRequest, Tuning};
use gelgrip_plugins::contact::ContactSummary;
use gelgrip_plugins::pipeline::{Needs, PipelineError, process_set};
use gelgrip_plugins::sensing::{sensor_geometry, sensor_reading};
use gelgrip_sim::load::{LoadProfile, LoadSpec};
use gelgrip_sim::scene_frames::SceneFrames;
use gelgrip_sim::servo_bus::SimServoBus;
use gelgrip_sim::world::{SharedWorld, World};
use rand::{Rng, SeedableRng};

use super::trial::{Rigging, SlipRow, Tally, TraceSet, TrialSpec, TrialStart, observe, states};

/// The ramp stops at this share of what `max_force_n` can hold.
pub const RAMP_TOP_SHARE: f64 = 0.8;
/// The object counts as dropped once it has slid this far along the pads (or lost every
/// contact), mm: a grasp that let it go this far has lost the object's pose.
pub const DROP_MM: f64 = 5.0;
/// The controller must hold the object within this long of starting to close, s.
const GRASP_MAX_S: f64 = 20.0;
/// The fingers close at this speed, deg/s (a quick grasp, so that trials are short).
const CLOSE_DEG_S: f64 = 60.0;
/// Sets read once the ramp has stopped (the reflex settles).
const AFTER_RAMP_S: f64 = 1.0;
/// Sets read before the load begins, s.
const BEFORE_LOAD_S: f64 = 0.3;

/// The sets of one trial, read, fused and controlled.
struct Loop<'r, 'a> {
    rig: &'r mut Rigging<'a>,
    frames: SceneFrames,
    clock: std::sync::Arc<VirtualClock>,
    bus: SimServoBus,
    geometry: Vec<(f64, f64, f64)>,
    results: Vec<Result<ContactSummary, PipelineError>>,
    start_us: u64,
    nth: usize,
}

impl Loop<'_, '_> {
    /// The time of the next set, µs.
    fn now_us(&self) -> u64 {
        self.start_us + self.nth as u64 * self.rig.set_period_us
    }

    /// Capture, read and fuse the next set.
    fn read(&mut self) -> anyhow::Result<FusedSet> {
        let now_us = self.now_us();
        self.clock
            .advance(now_us.saturating_sub(self.clock.now_us()));
        let jpegs = self.frames.capture(now_us, self.nth as u64)?;
        let views: Vec<&[u8]> = jpegs.iter().map(|j| &j[..]).collect();
        process_set(self.rig.pipes, &views, Needs::DEPTH, &mut self.results);
        let readings: Vec<_> = self
            .results
            .iter()
            .zip(&self.geometry)
            .map(|(r, g)| r.as_ref().ok().map(|s| sensor_reading(s, *g)))
            .collect();
        self.nth += 1;
        Ok(fuse(&self.rig.config.layout, &readings))
    }

    /// Close the fingers from open as a grasp that finds its own force, until it holds
    /// (an error naming `object` when it does not within [`GRASP_MAX_S`]).
    fn grasp(&mut self, object: &str) -> anyhow::Result<GraspController> {
        let mut ctl = controller(self.rig);
        while ctl.outcome().is_none() && self.now_us() < (GRASP_MAX_S * 1e6) as u64 {
            let set = self.read()?;
            self.control(&mut ctl, &set)?;
        }
        anyhow::ensure!(
            ctl.outcome().is_some_and(|o| o.reason.is_stable()),
            "{object}: the controller did not grasp it ({})",
            ctl.outcome()
                .map_or("no outcome".to_string(), |o| o.reason.to_string())
        );
        Ok(ctl)
    }

    /// Step `ctl` on `set` and write its goals.
    fn control(&mut self, ctl: &mut GraspController, set: &FusedSet) -> anyhow::Result<()> {
        let states = self
            .bus
            .read_state()
            .context("reading the simulated servos")?;
        let t_s = self.clock.now_us() as f64 / 1e6;
        let out = ctl.step(t_s, Some(set), &states);
        self.bus
            .write_goals(&out.goals)
            .context("writing the simulated servos")
    }
}

/// The controller for the trial: every finger, finding its own force, with the config's
/// current limit and `[grasp]` settings.
fn controller(rig: &Rigging<'_>) -> GraspController {
    let config = rig.config;
    let fingers = config.layout.fingers.len();
    let request = GraspRequest {
        target_force_n: config.grasp.preload_n,
        speed_deg_s: CLOSE_DEG_S,
        current_limit_ma: config.servos.current_limit_ma,
        fingers: (0..fingers).collect(),
        timeout_s: f64::INFINITY,
        auto_target: true,
    };
    let tuning = Tuning {
        grasp: config.grasp,
        ..Tuning::default()
    };
    let close = config
        .layout
        .fingers
        .iter()
        .map(|f| f.servo_range_deg)
        .collect();
    GraspController::new(request, tuning, close, vec![0.0; fingers])
}

/// Run one trial with the reflex.
pub fn run(rig: &mut Rigging<'_>, spec: &TrialSpec) -> anyhow::Result<(SlipRow, Vec<TraceSet>)> {
    let held = &spec.held.world;
    let (object, friction) = held
        .object()
        .map(|o| (o.spec().name.clone(), o.spec().friction))
        .context("the scene has no object")?;
    let config = rig.config;
    let fingers = config.layout.fingers.len().max(1) as f64;
    let world = World::new(&config.layout, held.scene().cloned()).into_shared();
    let clock = VirtualClock::new();
    let mut bus = SimServoBus::new(
        world.clone(),
        clock.clone(),
        &config.servos.ids,
        config.servos.current_limit_ma,
    )?;
    bus.configure()
        .context("configuring the simulated servos")?;
    let n = rig.pipes.len();
    let mut sets = Loop {
        frames: SceneFrames::new(world.clone(), &config.layout, rig.sim)?,
        clock,
        bus,
        geometry: sensor_geometry(&config.layout),
        results: (0..n).map(|_| Err(PipelineError::NoReference)).collect(),
        start_us: 0,
        nth: 0,
        rig,
    };
    let mut ctl = sets.grasp(&object)?;
    let (grip_n, (limit_n, push_n)) = {
        let w = lock(&world)?;
        (w.grip_n(), w.grip_loads_n())
    };
    anyhow::ensure!(
        limit_n > 0.0,
        "{object}: the grasp holds nothing (holding limit 0 N)"
    );
    let period = sets.rig.set_period_us;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(spec.seed);
    let load_start_us =
        sets.now_us() + (BEFORE_LOAD_S * 1e6) as u64 + rng.random_range(0..period.max(1));
    let rate = limit_n / spec.load_time_s;
    let top_n = RAMP_TOP_SHARE * friction * fingers * config.grasp.max_force_n;
    {
        let mut w = lock(&world)?;
        w.set_object_load(Some(LoadSpec {
            profile: LoadProfile::Ramp {
                rate_n_per_s: rate,
                max_n: Some(top_n),
            },
            start_s: load_start_us as f64 / 1e6,
            offset_n: -push_n,
        }));
    }
    let end_us = load_start_us + ((top_n / rate + AFTER_RAMP_S) * 1e6) as u64;
    let since_load = |t_us: u64| (t_us as f64 - load_start_us as f64) / 1e6;
    let mut tally = Tally::default();
    let mut pull_n: f64;
    loop {
        let now_us = sets.now_us();
        let set = sets.read()?;
        sets.control(&mut ctl, &set)?;
        let read = states(&sets.results);
        observe(
            &world,
            &read,
            since_load(now_us),
            rate,
            sets.nth - 1,
            &mut tally,
        )?;
        pull_n = (rate * since_load(now_us)).clamp(0.0, top_n);
        let w = lock(&world)?;
        let lost = w.grip_n() <= 0.0 || w.slip_truth().motion_mm >= DROP_MM;
        if lost || now_us >= end_us {
            break;
        }
    }
    let w = lock(&world)?;
    let start = TrialStart {
        object,
        friction,
        grip_n,
        holding_limit_n: limit_n,
        load_start_us,
        set_period_us: period,
    };
    let row = start.row(spec, &w, &tally, sets.nth, pull_n, true);
    Ok((row, tally.trace))
}

fn lock(
    world: &SharedWorld,
) -> anyhow::Result<std::sync::MutexGuard<'_, gelgrip_sim::world::World>> {
    world
        .lock()
        .map_err(|_| anyhow::anyhow!("the world was poisoned"))
}
