//! `gelgrip bench soak --minutes N [--seed S] [--json]`: the product under random faults.
//!
//! It runs the simulated gripper with its dashboard in this process (the library's session,
//! as `gelgrip run` does; the tennis ball in reach) and, through the dashboard's API only, injects a random fault every two seconds:
//! corrupt bytes, a sensor dropping out, a slow sensor, a hub unplug, a servo overload, or a
//! burst of HTTP commands (grasps, releases, state reads, malformed requests). Twice a
//! second it reads the state and the process's RSS. At the end it stops the run (a
//! shutdown event, as SIGTERM gives `gelgrip run`) and checks the invariants: no panic
//! (counted by a panic hook, and a run task that did not panic); every frame the hub delivered is in a set,
//! dropped with a reason, or among the last sets still pending; no duplicate; RSS within
//! bounds after warm-up; the fingers always in a documented controller phase; no 5xx
//! answer. The exit code is 1 when an invariant fails.

use clap::Args;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::runtime::RuntimeEvent;
use gelgrip_controller::runtime::options::RunOptions;
use tokio::sync::mpsc;

use crate::rig::{Rig, RunEnd};

/// The controller phases docs/control.md documents.
pub(crate) const PHASES: [&str; 7] = [
    "open", "approach", "contact", "squeeze", "hold", "release", "fault",
];
/// Sensors of the default gripper and the fingers.
const SENSORS: [&str; 7] = [
    "f1.tip", "f1.base", "f2.tip", "f2.base", "f3.tip", "f3.base", "palm",
];
pub(crate) const FINGERS: [&str; 3] = ["f1", "f2", "f3"];
/// Frames that may still wait in the gate at the end: two sets of seven.
pub(crate) const PENDING_FRAMES: u64 = 14;

/// The `--json` report.
#[derive(Debug, Serialize)]
pub struct SoakReport {
    minutes: f64,
    seed: u64,
    /// All invariants held.
    passed: bool,
    panics: u64,
    unaccounted_losses: u64,
    duplicates: u64,
    rss_warm_kb: u64,
    rss_max_kb: u64,
    rss_growth_pct: f64,
    /// Faults injected, by kind.
    faults: BTreeMap<&'static str, u64>,
    http_requests: u64,
    /// Answers by class (`2xx`, `4xx`, `5xx`; `none`: no answer within 30 s).
    http_status: BTreeMap<String, u64>,
    state_samples: u64,
    undocumented_states: u64,
    sets: u64,
    frames_received: u64,
    drops: serde_json::Value,
    sets_rejected: serde_json::Value,
    /// Faults the run itself listed (recovered servo faults, watchdog holds).
    run_faults: u64,
    end_reason: String,
    exit_code: Option<i32>,
}

/// How long a request may take: a grasp answers when it is done (its own timeout is 20 s).
const HTTP_TIMEOUT: Duration = Duration::from_secs(30);

/// One HTTP/1.1 request with `Connection: close`; the status and the body.
pub(crate) async fn http(
    addr: &str,
    method: &str,
    path: &str,
    body: &str,
) -> Option<(u16, String)> {
    let attempt = async {
        let mut s = tokio::net::TcpStream::connect(addr).await.ok()?;
        let req = format!(
            "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        );
        s.write_all(req.as_bytes()).await.ok()?;
        let mut raw = Vec::new();
        s.read_to_end(&mut raw).await.ok()?;
        let text = String::from_utf8_lossy(&raw).into_owned();
        let status = text.split_whitespace().nth(1)?.parse().ok()?;
        let body = text.split_once("\r\n\r\n").map(|(_, b)| b.to_string())?;
        Some((status, body))
    };
    tokio::time::timeout(HTTP_TIMEOUT, attempt)
        .await
        .ok()
        .flatten()
}

pub(crate) fn rss_kb(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

/// Answers by class, shared with the bursts running in the background.
pub(crate) type StatusCounts = std::sync::Arc<std::sync::Mutex<BTreeMap<String, u64>>>;

struct Soak {
    addr: String,
    rng: Pcg64Mcg,
    faults: BTreeMap<&'static str, u64>,
    status: StatusCounts,
    requests: u64,
    bursts: tokio::task::JoinSet<()>,
}

/// Send a request and count its answer's class (`none`: no answer within the timeout).
pub(crate) async fn counted(
    addr: String,
    status: StatusCounts,
    method: &str,
    path: &str,
    body: &str,
) -> Option<String> {
    let answer = http(&addr, method, path, body).await;
    let class = answer
        .as_ref()
        .map_or("none".to_string(), |(s, _)| format!("{}xx", s / 100));
    if let Ok(mut s) = status.lock() {
        *s.entry(class).or_default() += 1;
    }
    answer.map(|(_, b)| b)
}

impl Soak {
    async fn call(&mut self, method: &str, path: &str, body: &str) -> Option<String> {
        self.requests += 1;
        counted(self.addr.clone(), self.status.clone(), method, path, body).await
    }

    fn sensor(&mut self) -> &'static str {
        SENSORS[self.rng.random_range(0..SENSORS.len())]
    }

    /// Inject one random fault; returns what to undo after `hold`.
    async fn inject(&mut self) -> Option<(Duration, String)> {
        let kind = self.rng.random_range(0..6);
        let name = [
            "corrupt",
            "dropout",
            "slow",
            "unplug",
            "servo_overload",
            "http_burst",
        ][kind];
        *self.faults.entry(name).or_default() += 1;
        match kind {
            0..=2 => {
                let sensor = self.sensor();
                let fault = match kind {
                    0 => r#""corrupt_rate": 0.3"#,
                    1 => r#""drop_rate": 1.0"#,
                    _ => r#""capture_delay_us": 3000"#,
                };
                self.call(
                    "POST",
                    "/api/sim/fault",
                    &format!(r#"{{"sensor": "{sensor}", {fault}}}"#),
                )
                .await;
                let hold = Duration::from_millis(self.rng.random_range(300..1500));
                Some((hold, format!(r#"{{"sensor": "{sensor}"}}"#)))
            }
            3 => {
                let ms = self.rng.random_range(100..1000);
                self.call("POST", "/api/sim/unplug", &format!(r#"{{"ms": {ms}}}"#))
                    .await;
                None
            }
            4 => {
                let finger = FINGERS[self.rng.random_range(0..FINGERS.len())];
                self.call(
                    "POST",
                    "/api/sim/servo",
                    &format!(r#"{{"finger": "{finger}", "fault": "overload"}}"#),
                )
                .await;
                None
            }
            _ => {
                for (method, path, body) in burst(&mut self.rng) {
                    self.requests += 1;
                    let (addr, status) = (self.addr.clone(), self.status.clone());
                    self.bursts.spawn(async move {
                        counted(addr, status, method, path, body).await;
                    });
                }
                None
            }
        }
    }
}

/// The requests a burst draws from: grasps, releases, state reads, malformed bodies,
/// unknown paths, stops.
const BURST_REQUESTS: [(&str, &str, &str); 6] = [
    ("POST", "/api/grasp", r#"{"target_force_n": 2.0}"#),
    ("POST", "/api/release", "{}"),
    ("GET", "/api/state", ""),
    ("POST", "/api/grasp", "{not json"),
    ("GET", "/api/nothing-here", ""),
    ("POST", "/api/stop", "{}"),
];

/// Twenty HTTP commands sent at once, answered in the background (a grasp answers when it
/// is done), drawn from [`BURST_REQUESTS`].
pub(crate) fn burst(rng: &mut Pcg64Mcg) -> Vec<(&'static str, &'static str, &'static str)> {
    (0..20)
        .map(|k| BURST_REQUESTS[(k + rng.random_range(0..6)) % BURST_REQUESTS.len()])
        .collect()
}

/// Count every panic in this process from now on (then the previous hook reports it).
pub(crate) fn count_panics() -> Arc<AtomicU64> {
    let panics = Arc::new(AtomicU64::new(0));
    let seen = panics.clone();
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        seen.fetch_add(1, Ordering::Relaxed);
        previous(info);
    }));
    panics
}

/// The gripper under test, running in this process with its dashboard.
pub(crate) struct Gripper {
    pub(crate) addr: String,
    /// The simulated world (`None` on real hardware).
    pub(crate) world: Option<gelgrip_sim::world::SharedWorld>,
    stop: mpsc::Sender<RuntimeEvent>,
    run: tokio::task::JoinHandle<anyhow::Result<RunEnd>>,
}

impl Gripper {
    /// Start the gripper on `clock` with its dashboard on a free local port.
    pub(crate) async fn start(rig: &dyn Rig, clock: ClockKind) -> anyhow::Result<Self> {
        let options = RunOptions {
            http: Some(std::net::SocketAddr::from(([127, 0, 0, 1], 0))),
            clock,
            ..RunOptions::default()
        };
        let started = rig.start(&options).await?;
        let addr = started
            .dashboard_url
            .as_deref()
            .context("the run serves no dashboard")?
            .trim_start_matches("http://")
            .trim_end_matches('/')
            .to_string();
        Ok(Self {
            addr,
            world: started.world,
            stop: started.events,
            run: started.end,
        })
    }

    /// Stop the run and take its report (`None` if the run's task panicked).
    pub(crate) async fn stop(self) -> anyhow::Result<Option<RunEnd>> {
        let _ = self.stop.send(RuntimeEvent::Shutdown).await;
        match self.run.await {
            Ok(end) => end.map(Some),
            Err(e) if e.is_panic() => Ok(None),
            Err(e) => Err(e).context("the run's task"),
        }
    }
}

/// Run the soak on the clock `args` names; returns the exit code, or an error when an
/// invariant failed (after the report).
pub async fn run(rig: &dyn Rig, args: BenchSoakArgs) -> anyhow::Result<u8> {
    match args.clock {
        SoakClock::Virtual => crate::soak_storm::run(rig, &args).await,
        SoakClock::Real if args.faults.is_some() => {
            bail!("--faults counts the virtual soak's fault events: add --clock virtual")
        }
        SoakClock::Real => run_real(rig, &args, args.minutes.unwrap_or(10.0)).await,
    }
}

/// The soak on the real clock for `minutes`, a fault every two seconds.
async fn run_real(rig: &dyn Rig, args: &BenchSoakArgs, minutes: f64) -> anyhow::Result<u8> {
    let panic_count = count_panics();
    let gripper = Gripper::start(rig, ClockKind::Real).await?;
    let addr = gripper.addr.clone();
    let mut soak = Soak {
        addr,
        rng: Pcg64Mcg::seed_from_u64(args.seed),
        faults: BTreeMap::new(),
        status: StatusCounts::default(),
        requests: 0,
        bursts: tokio::task::JoinSet::new(),
    };
    let total = Duration::from_secs_f64(minutes * 60.0);
    let warm_up = (total / 10).clamp(Duration::from_secs(5), Duration::from_secs(60));
    let start = Instant::now();
    // The tennis ball within reach, so grasps find something.
    soak.call("POST", "/api/sim/scene", r#"{"name": "tennis-ball"}"#)
        .await;
    let seen = soak_for(&mut soak, start, total, warm_up).await;
    let Seen {
        rss_warm,
        rss_max,
        samples,
        undocumented,
    } = seen;
    while soak.bursts.join_next().await.is_some() {}
    let http_status = soak.status.lock().map(|s| s.clone()).unwrap_or_default();
    let report = gripper.stop().await?;
    // The exit code `gelgrip run` would give: 101 for a panic.
    let exit_code = report.as_ref().map_or(101, |r| i32::from(r.exit_code));
    let run = match report {
        Some(r) => r.report,
        None => serde_json::Value::Null,
    };
    let count = |key: &str| -> u64 {
        run[key]
            .as_object()
            .map_or(0, |o| o.values().filter_map(|v| v.as_u64()).sum())
    };
    let sets = run["sets"].as_u64().unwrap_or(0);
    let frames = run["frames_received"].as_u64().unwrap_or(0);
    // Frames in emitted sets (fewer than 7 per set while a slow sensor is excluded) plus
    // frames dropped with a reason.
    let accounted = run["frames_in_sets"].as_u64().unwrap_or(0) + count("drops");
    let unaccounted =
        frames.saturating_sub(accounted + PENDING_FRAMES) + accounted.saturating_sub(frames);
    let duplicates = run["drops"]["duplicate"].as_u64().unwrap_or(0);
    let rss_growth_pct = if rss_warm > 0 {
        (rss_max.saturating_sub(rss_warm)) as f64 / rss_warm as f64 * 100.0
    } else {
        0.0
    };
    let panics = panic_count.load(Ordering::Relaxed);
    let five_xx = http_status.get("5xx").copied().unwrap_or(0);
    let unanswered = http_status.get("none").copied().unwrap_or(0);
    let passed = panics == 0
        && unaccounted == 0
        && duplicates == 0
        && rss_growth_pct <= 10.0
        && undocumented == 0
        && five_xx == 0
        && unanswered == 0
        && samples > 0
        && exit_code == 0;
    let report = SoakReport {
        minutes,
        seed: args.seed,
        passed,
        panics,
        unaccounted_losses: unaccounted,
        duplicates,
        rss_warm_kb: rss_warm,
        rss_max_kb: rss_max,
        rss_growth_pct,
        faults: soak.faults,
        http_requests: soak.requests,
        http_status,
        state_samples: samples,
        undocumented_states: undocumented,
        sets,
        frames_received: frames,
        drops: run["drops"].clone(),
        sets_rejected: run["sets_rejected"].clone(),
        run_faults: run["faults"].as_array().map_or(0, |f| f.len() as u64),
        end_reason: run["end_reason"].as_str().unwrap_or("").to_string(),
        exit_code: Some(exit_code),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print_report(&report, five_xx);
    }
    if !passed {
        bail!("soak invariants failed (see the report)");
    }
    Ok(0)
}

/// What the soak saw of the run while it injected faults.
struct Seen {
    /// RSS at the end of the warm-up, kB.
    rss_warm: u64,
    /// The largest RSS after it, kB.
    rss_max: u64,
    /// `/api/state` samples read.
    samples: u64,
    /// Samples with a finger phase the API does not document.
    undocumented: u64,
}

/// Soak for `total` from `start`: sample the state and the RSS every half second, inject a fault every
/// 2 s once half the warm-up has passed, undo each when its time is up (and the rest at
/// the end).
async fn soak_for(soak: &mut Soak, start: Instant, total: Duration, warm_up: Duration) -> Seen {
    let (mut rss_warm, mut rss_max) = (0u64, 0u64);
    let (mut samples, mut undocumented) = (0u64, 0u64);
    let mut next_fault = start + Duration::from_secs(2);
    let mut undo: Vec<(Instant, String)> = Vec::new();
    let mut last_progress = start;
    while start.elapsed() < total {
        tokio::time::sleep(Duration::from_millis(500)).await;
        let now = Instant::now();
        if let Some(body) = soak.call("GET", "/api/state", "").await
            && let Ok(state) = serde_json::from_str::<serde_json::Value>(&body)
        {
            samples += 1;
            let fingers = state["fingers"].as_array().cloned().unwrap_or_default();
            if fingers
                .iter()
                .any(|f| !f["phase"].as_str().is_some_and(|p| PHASES.contains(&p)))
            {
                undocumented += 1;
            }
        }
        let rss = rss_kb(std::process::id());
        if now.duration_since(start) < warm_up {
            rss_warm = rss;
        } else {
            rss_max = rss_max.max(rss);
        }
        for (_, body) in undo.iter().filter(|(at, _)| *at <= now) {
            soak.call("POST", "/api/sim/fault", body).await;
        }
        undo.retain(|(at, _)| *at > now);
        if now >= next_fault && now.duration_since(start) >= warm_up / 2 {
            if let Some((hold, body)) = soak.inject().await {
                undo.push((now + hold, body));
            }
            next_fault = now + Duration::from_secs(2);
        }
        if now.duration_since(last_progress) >= Duration::from_secs(30) {
            last_progress = now;
            tracing::info!(
                elapsed_s = start.elapsed().as_secs(),
                faults = soak.faults.values().sum::<u64>(),
                rss_kb = rss,
                "soaking"
            );
        }
    }
    for (_, body) in undo.drain(..) {
        soak.call("POST", "/api/sim/fault", &body).await;
    }
    Seen {
        rss_warm,
        rss_max,
        samples,
        undocumented,
    }
}

/// The report as text.
fn print_report(report: &SoakReport, five_xx: u64) {
    println!(
        "soak {:.1} min (seed {}): {}",
        report.minutes,
        report.seed,
        if report.passed { "passed" } else { "FAILED" }
    );
    println!(
        "  panics {}, unaccounted losses {}, duplicates {}, undocumented states {}, 5xx {}",
        report.panics,
        report.unaccounted_losses,
        report.duplicates,
        report.undocumented_states,
        five_xx
    );
    println!(
        "  RSS {} kB after warm-up, {} kB at most: {:+.1} %",
        report.rss_warm_kb, report.rss_max_kb, report.rss_growth_pct
    );
    println!("  faults injected {:?}", report.faults);
    println!(
        "  {} sets, {} frames; drops {}; rejected {}",
        report.sets, report.frames_received, report.drops, report.sets_rejected
    );
    println!(
        "  HTTP {} requests: {:?}",
        report.http_requests, report.http_status
    );
}

/// The clock a soak runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SoakClock {
    /// Wall-clock time: a fault every two seconds through the dashboard's API.
    Real,
    /// Virtual time at the host's pace: a seeded storm of faults in the simulated world's
    /// time (docs/soak.md).
    Virtual,
}

/// `gelgrip bench soak`.
#[derive(Debug, Args)]
pub struct BenchSoakArgs {
    /// How long, in minutes: wall-clock minutes on the real clock (default 10); virtual
    /// minutes on the virtual clock (no limit unless given: it ends after `--faults`).
    #[arg(long, value_parser = parse_minutes)]
    pub minutes: Option<f64>,
    /// The clock: `real` (today's soak), or `virtual` (a storm of fault events).
    #[arg(long, value_enum, default_value = "real")]
    pub clock: SoakClock,
    /// On the virtual clock: end once this many fault events were injected (default
    /// 100000; every corrupted or dropped frame is one, every unplug, slow-sensor episode,
    /// servo overload or HTTP burst is one).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..))]
    pub faults: Option<u64>,
    /// Seed of the fault schedule.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

fn parse_minutes(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if (0.1..=10_080.0).contains(&v) => Ok(v),
        _ => Err(format!("`{s}`: expected minutes in [0.1, 10080]")),
    }
}
