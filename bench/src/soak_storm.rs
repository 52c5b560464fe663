//! `gelgrip bench soak --clock virtual [--faults N] [--minutes M] [--seed S] [--json]`: the
//! soak on the virtual clock, under a storm of fault events.
//!
//! The simulated gripper runs in this process with its dashboard, on the virtual clock (at
//! the host's pace), the tennis ball in reach. A seeded [`FaultStorm`] in the simulated
//! world injects an episode every 250 ms of virtual time on average: a sensor corrupting or
//! dropping most of its frames, a slow sensor, a hub unplug, a servo overload, or a burst of
//! twenty HTTP commands, which this bench sends to the dashboard as it comes due. Every
//! corrupted or dropped frame is one fault event, every other episode one. The soak ends
//! once `--faults` events were injected (default 100,000), or after `--minutes` of virtual
//! time.
//!
//! The invariants are checked on every state sample (about ten a second of wall time):
//! every frame received is in a set, dropped with a reason, or among the last two sets'
//! pending; no frame is taken twice; every finger in a documented phase; no servo left with
//! a hardware error for more than a second of virtual time (the controller reboots it, or
//! the run ends with torque off). At the end: no panic, no set delivered twice (the run's
//! own count), no 5xx and every request answered, the run ended as asked, and the peak RSS
//! of the last quarter within 5% of the first quarter's. The exit code is 1 when any fails.
//! A failing seed replays the same storm at the same virtual times; the HTTP bursts' own
//! requests land at the host's pace.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use gelgrip_controller::clock::ClockKind;
use gelgrip_sim::fault_storm::{FaultStorm, FaultTally, StormRates};
use gelgrip_sim::world::SharedWorld;
use rand::SeedableRng;
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use serde_json::Value;

use crate::rig::Rig;
use crate::soak::{
    BenchSoakArgs, FINGERS, Gripper, PENDING_FRAMES, PHASES, StatusCounts, burst, count_panics,
    counted, http, rss_kb,
};

/// The default number of fault events.
const DEFAULT_FAULTS: u64 = 100_000;
/// How often the bench looks at the world (bursts due, progress), wall time.
const POLL: Duration = Duration::from_millis(20);
/// How often it samples the state and the RSS, wall time.
const SAMPLE: Duration = Duration::from_millis(100);
/// The longest a servo may report a hardware error, virtual s.
const SERVO_ERROR_LIMIT_S: f64 = 1.0;
/// Requests in flight beyond which the bench waits for answers before sending more.
const MAX_IN_FLIGHT: usize = 400;
/// Allowed growth of the last quarter's peak RSS over the first quarter's.
const RSS_GROWTH_LIMIT: f64 = 0.05;

/// The `--json` report.
#[derive(Debug, Serialize)]
pub struct StormReport {
    clock: &'static str,
    seed: u64,
    /// All invariants held.
    passed: bool,
    /// Fault events injected, all kinds.
    faults_injected: u64,
    /// Events by kind: `corrupt` and `dropout` frames; `slow`, `unplug`, `servo_overload`
    /// and `http_burst` episodes.
    faults: FaultTally,
    panics: u64,
    /// Frames neither in a set nor dropped with a reason (most seen on any sample, and at
    /// the end).
    frames_unaccounted: u64,
    /// Sets delivered again or out of order (the run's count).
    duplicate_sets: u64,
    /// Frames the gate saw twice.
    duplicate_frames: u64,
    rss_mb_first_quarter: f64,
    rss_mb_last_quarter: f64,
    virtual_s: f64,
    wall_s: f64,
    sets: u64,
    frames_received: u64,
    drops: Value,
    sets_rejected: Value,
    state_samples: u64,
    undocumented_states: u64,
    /// Times a servo reported a hardware error for longer than a second of virtual time.
    servo_faults_unrecovered: u64,
    http_requests: u64,
    http_status: BTreeMap<String, u64>,
    /// Faults the run listed (recovered servo faults, watchdog holds).
    run_faults: u64,
    end_reason: String,
    exit_code: i32,
}

/// What the samples saw.
#[derive(Debug, Default)]
struct Watch {
    samples: u64,
    undocumented: u64,
    unaccounted_max: u64,
    duplicate_frames: u64,
    /// Per finger: since when (virtual s) its servo has reported an error.
    servo_error_since: [Option<f64>; 3],
    servo_unrecovered: u64,
    rss_first_kb: u64,
    rss_last_kb: u64,
}

impl Watch {
    /// Check one `/api/state` sample.
    fn state(&mut self, state: &Value) {
        self.samples += 1;
        let fingers = state["fingers"].as_array().map_or(&[][..], Vec::as_slice);
        if fingers
            .iter()
            .any(|f| !f["phase"].as_str().is_some_and(|p| PHASES.contains(&p)))
        {
            self.undocumented += 1;
        }
        let sync = &state["sync"];
        let received = sync["frames_received"].as_u64().unwrap_or(0);
        let accounted = sync["frames_in_sets"].as_u64().unwrap_or(0) + total(&sync["drops"]);
        self.unaccounted_max = self.unaccounted_max.max(unaccounted(received, accounted));
        self.duplicate_frames = self
            .duplicate_frames
            .max(sync["drops"]["duplicate"].as_u64().unwrap_or(0));
        let t_s = state["t_s"].as_f64().unwrap_or(0.0);
        let servos = state["servos"].as_array().map_or(&[][..], Vec::as_slice);
        for (finger, since) in self.servo_error_since.iter_mut().enumerate() {
            let erring = servos
                .get(finger)
                .and_then(|s| s["errors"].as_array())
                .is_some_and(|e| !e.is_empty());
            match (*since, erring) {
                (None, true) => *since = Some(t_s),
                (Some(t0), true) if t_s - t0 > SERVO_ERROR_LIMIT_S => {
                    self.servo_unrecovered += 1;
                    tracing::error!(
                        finger = FINGERS[finger],
                        since_s = t0,
                        "servo not recovered"
                    );
                    *since = Some(t_s);
                }
                (_, false) => *since = None,
                _ => {}
            }
        }
    }

    /// Take an RSS sample at `progress` (0 to 1) through the run.
    fn rss(&mut self, progress: f64) {
        let kb = rss_kb(std::process::id());
        if progress < 0.25 {
            self.rss_first_kb = self.rss_first_kb.max(kb);
        } else if progress >= 0.75 {
            self.rss_last_kb = self.rss_last_kb.max(kb);
        }
    }
}

/// The sum of a `{reason: count}` object.
fn total(counts: &Value) -> u64 {
    counts
        .as_object()
        .map_or(0, |o| o.values().filter_map(Value::as_u64).sum())
}

/// Frames received but neither in a set nor dropped, beyond the two sets the gate may still
/// hold; or accounted for but never received.
fn unaccounted(received: u64, accounted: u64) -> u64 {
    received.saturating_sub(accounted + PENDING_FRAMES) + accounted.saturating_sub(received)
}

/// The bench's side of the storm: the dashboard's address, the HTTP bursts in flight.
struct Driver {
    addr: String,
    rng: Pcg64Mcg,
    status: StatusCounts,
    requests: u64,
    in_flight: tokio::task::JoinSet<()>,
}

impl Driver {
    /// Send one burst of twenty requests in the background.
    async fn burst(&mut self) {
        while self.in_flight.len() > MAX_IN_FLIGHT {
            self.in_flight.join_next().await;
        }
        while self.in_flight.try_join_next().is_some() {}
        for (method, path, body) in burst(&mut self.rng) {
            self.requests += 1;
            let (addr, status) = (self.addr.clone(), self.status.clone());
            self.in_flight.spawn(async move {
                counted(addr, status, method, path, body).await;
            });
        }
    }
}

/// The storm's tally, the bursts due and the virtual time, in one look at the world.
fn look(world: &SharedWorld) -> anyhow::Result<(FaultTally, u64, f64)> {
    let mut w = world
        .lock()
        .map_err(|_| anyhow::anyhow!("the simulated world has failed (a panic held its lock)"))?;
    Ok((
        w.fault_tally().unwrap_or_default(),
        w.take_http_bursts(),
        w.elapsed_s(),
    ))
}

/// Start the storm in `world`; from then on its episodes strike at every trigger.
fn start_storm(world: &SharedWorld, seed: u64) -> anyhow::Result<()> {
    let mut w = world
        .lock()
        .map_err(|_| anyhow::anyhow!("the simulated world has failed"))?;
    let (sensors, fingers) = (w.sensors(), w.fingers());
    w.set_fault_storm(Some(FaultStorm::new(
        seed,
        StormRates::default(),
        sensors,
        fingers,
    )));
    Ok(())
}

/// End the storm: what it opened is closed (sensors healthy, hub plugged in); its tally.
fn end_storm(world: &SharedWorld) -> anyhow::Result<FaultTally> {
    let mut w = world
        .lock()
        .map_err(|_| anyhow::anyhow!("the simulated world has failed"))?;
    let tally = w.fault_tally().unwrap_or_default();
    w.set_fault_storm(None);
    for sensor in 0..w.sensors() {
        w.inject_faults(sensor, None);
    }
    w.unplug_hub(0);
    Ok(tally)
}

/// Storm the gripper until `faults` events or `virtual_s` of virtual time; what it saw.
async fn storm(
    driver: &mut Driver,
    world: &SharedWorld,
    faults: u64,
    virtual_s: f64,
) -> anyhow::Result<Watch> {
    let mut watch = Watch::default();
    let (mut last_sample, mut last_log) = (Instant::now(), Instant::now());
    let bar = crate::progress::bar(faults, "fault events");
    loop {
        tokio::time::sleep(POLL).await;
        let (tally, bursts, t_s) = look(world)?;
        for _ in 0..bursts {
            driver.burst().await;
        }
        let progress = (tally.total() as f64 / faults as f64).max(t_s / virtual_s);
        bar.set_position(tally.total().min(faults));
        if last_sample.elapsed() >= SAMPLE {
            last_sample = Instant::now();
            if let Some((_, body)) = http(&driver.addr, "GET", "/api/state", "").await
                && let Ok(state) = serde_json::from_str::<Value>(&body)
            {
                watch.state(&state);
            }
            watch.rss(progress);
        }
        if bar.is_hidden() && last_log.elapsed() >= Duration::from_secs(30) {
            last_log = Instant::now();
            tracing::info!(events = tally.total(), virtual_s = t_s, "storming");
        }
        if progress >= 1.0 {
            break;
        }
    }
    bar.finish_and_clear();
    Ok(watch)
}

/// Run the virtual-clock soak; the exit code, or an error when an invariant failed (after
/// the report).
pub async fn run(rig: &dyn Rig, args: &BenchSoakArgs) -> anyhow::Result<u8> {
    let panic_count = count_panics();
    let faults = args.faults.unwrap_or(DEFAULT_FAULTS);
    let virtual_s = args.minutes.map_or(f64::INFINITY, |m| m * 60.0);
    let wall = Instant::now();
    let gripper = Gripper::start(rig, ClockKind::Virtual).await?;
    let world = gripper
        .world
        .clone()
        .context("the virtual soak needs the simulated gripper (hub.transport = \"sim\")")?;
    let mut driver = Driver {
        addr: gripper.addr.clone(),
        rng: Pcg64Mcg::seed_from_u64(args.seed),
        status: StatusCounts::default(),
        requests: 0,
        in_flight: tokio::task::JoinSet::new(),
    };
    // The tennis ball within reach, so grasps find something.
    http(
        &driver.addr,
        "POST",
        "/api/sim/scene",
        r#"{"name": "tennis-ball"}"#,
    )
    .await
    .context("the dashboard did not answer")?;
    start_storm(&world, args.seed)?;
    let mut watch = storm(&mut driver, &world, faults, virtual_s).await?;
    let tally = end_storm(&world)?;
    let (_, _, t_s) = look(&world)?;
    while driver.in_flight.join_next().await.is_some() {}
    let end = gripper.stop().await?;
    let report = storm_report(
        args,
        Ended {
            tally,
            virtual_s: t_s,
            wall_s: wall.elapsed().as_secs_f64(),
            panics: panic_count.load(std::sync::atomic::Ordering::Relaxed),
            faults_asked: faults,
        },
        &mut watch,
        &driver,
        end,
    );
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_report(&report);
    }
    if !report.passed {
        bail!("soak invariants failed (see the report)");
    }
    Ok(0)
}

/// How the storm ended.
struct Ended {
    tally: FaultTally,
    virtual_s: f64,
    wall_s: f64,
    panics: u64,
    faults_asked: u64,
}

/// The report from what was seen, the run's own report and the invariants.
fn storm_report(
    args: &BenchSoakArgs,
    ended: Ended,
    watch: &mut Watch,
    driver: &Driver,
    end: Option<crate::rig::RunEnd>,
) -> StormReport {
    let http_status = driver.status.lock().map(|s| s.clone()).unwrap_or_default();
    // The exit code `gelgrip run` would give: 101 for a panic.
    let exit_code = end.as_ref().map_or(101, |r| i32::from(r.exit_code));
    let run = end.map_or(Value::Null, |r| r.report);
    let received = run["frames_received"].as_u64().unwrap_or(0);
    let accounted = run["frames_in_sets"].as_u64().unwrap_or(0) + total(&run["drops"]);
    let frames_unaccounted = watch.unaccounted_max.max(unaccounted(received, accounted));
    let duplicate_frames = watch
        .duplicate_frames
        .max(run["drops"]["duplicate"].as_u64().unwrap_or(0));
    let duplicate_sets = run["duplicate_sets"].as_u64().unwrap_or(u64::MAX);
    let (first, last) = (watch.rss_first_kb as f64, watch.rss_last_kb as f64);
    let rss_flat = first > 0.0 && last > 0.0 && last <= first * (1.0 + RSS_GROWTH_LIMIT);
    let bad_http = http_status.get("5xx").copied().unwrap_or(0)
        + http_status.get("none").copied().unwrap_or(0);
    let enough = ended.tally.total() >= ended.faults_asked || args.minutes.is_some();
    let passed = ended.panics == 0
        && frames_unaccounted == 0
        && duplicate_sets == 0
        && duplicate_frames == 0
        && watch.undocumented == 0
        && watch.servo_unrecovered == 0
        && bad_http == 0
        && watch.samples > 0
        && rss_flat
        && enough
        && exit_code == 0;
    StormReport {
        clock: "virtual",
        seed: args.seed,
        passed,
        faults_injected: ended.tally.total(),
        faults: ended.tally,
        panics: ended.panics,
        frames_unaccounted,
        duplicate_sets,
        duplicate_frames,
        rss_mb_first_quarter: first / 1024.0,
        rss_mb_last_quarter: last / 1024.0,
        virtual_s: ended.virtual_s,
        wall_s: ended.wall_s,
        sets: run["sets"].as_u64().unwrap_or(0),
        frames_received: received,
        drops: run["drops"].clone(),
        sets_rejected: run["sets_rejected"].clone(),
        state_samples: watch.samples,
        undocumented_states: watch.undocumented,
        servo_faults_unrecovered: watch.servo_unrecovered,
        http_requests: driver.requests,
        http_status,
        run_faults: run["faults"].as_array().map_or(0, |f| f.len() as u64),
        end_reason: run["end_reason"].as_str().unwrap_or("").to_string(),
        exit_code,
    }
}

/// The report as text.
fn print_report(r: &StormReport) {
    println!(
        "soak on the virtual clock (seed {}): {} — {} fault events in {:.0} s virtual, {:.0} s wall",
        r.seed,
        if r.passed { "passed" } else { "FAILED" },
        r.faults_injected,
        r.virtual_s,
        r.wall_s
    );
    println!(
        "  events: corrupt {}, dropout {}, slow {}, unplug {}, servo overload {}, HTTP bursts {}",
        r.faults.corrupt,
        r.faults.dropout,
        r.faults.slow,
        r.faults.unplug,
        r.faults.servo_overload,
        r.faults.http_burst
    );
    println!(
        "  panics {}, frames unaccounted {}, duplicate sets {}, duplicate frames {}, \
         undocumented states {}, servos not recovered {}",
        r.panics,
        r.frames_unaccounted,
        r.duplicate_sets,
        r.duplicate_frames,
        r.undocumented_states,
        r.servo_faults_unrecovered
    );
    println!(
        "  peak RSS {:.1} MB in the first quarter, {:.1} MB in the last",
        r.rss_mb_first_quarter, r.rss_mb_last_quarter
    );
    println!(
        "  {} sets, {} frames; drops {}; rejected {}",
        r.sets, r.frames_received, r.drops, r.sets_rejected
    );
    println!("  HTTP {} requests: {:?}", r.http_requests, r.http_status);
    println!(
        "  run: {} faults listed, end {}, exit {}",
        r.run_faults, r.end_reason, r.exit_code
    );
}
