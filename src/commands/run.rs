//! `gelgrip run`: acquire and gate synchronized frame sets until the duration ends, a signal
//! arrives or the hub fails; log statistics once a second to stderr; print a report.

use std::sync::Arc;

use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::clock::{Clock, ClockKind};

use crate::cli::{ClockArg, RunArgs};
use crate::output::{RunReport, latency_ms};
use crate::wiring;

/// Resolves on SIGINT or SIGTERM.
pub async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

/// Resolves at `deadline_us` on a real clock; never on a virtual one (whose time only moves
/// with the work, so the loop checks it after each set instead).
async fn real_deadline(clock: Arc<dyn Clock>, deadline_us: Option<u64>) {
    match deadline_us {
        Some(d) if clock.kind() == ClockKind::Real => clock.sleep_until(d).await,
        _ => std::future::pending().await,
    }
}

struct Progress {
    last_log_us: u64,
    last_sets: u64,
}

impl Progress {
    fn log(&mut self, acq: &Acquisition, now_us: u64) {
        if now_us < self.last_log_us + 1_000_000 {
            return;
        }
        let stats = acq.gate().stats();
        let window_s = (now_us - self.last_log_us) as f64 / 1e6;
        let rate = (stats.sets - self.last_sets) as f64 / window_s;
        tracing::info!(
            sets = stats.sets,
            rate_hz = format!("{rate:.1}"),
            spread_us_p99 = stats.spread_us_p99().unwrap_or(0),
            frames_dropped = stats.drops.total(),
            sets_rejected = stats.sets_rejected.total(),
            "acquisition"
        );
        self.last_log_us = now_us;
        self.last_sets = stats.sets;
    }
}

/// Run the command; returns the exit code.
pub async fn run(args: RunArgs) -> anyhow::Result<u8> {
    let registry = wiring::registry();
    let config = wiring::load_config(args.config.as_deref(), &registry)?;
    let clock_arg = args.clock.unwrap_or(ClockArg::Real);
    let clock = wiring::make_clock(clock_arg);
    if !args.headless {
        tracing::info!(
            "the dashboard ({}) arrives with the web dashboard issue; running without it",
            config.http.bind
        );
    }
    let mut acq = wiring::open_acquisition(&config, &registry, clock.clone()).await?;
    let description = acq.hub().describe().clone();
    tracing::info!(
        transport = description.transport,
        sensors = description.sensors,
        trigger = description.trigger.as_str(),
        max_spread_us = acq.gate().limits().max_spread_us,
        max_age_us = acq.gate().limits().max_age_us,
        "acquiring"
    );
    let start = clock.now_us();
    let deadline = args.duration.map(|s| start + (s * 1e6) as u64);
    let mut progress = Progress {
        last_log_us: start,
        last_sets: 0,
    };
    let mut faults = Vec::new();
    let shutdown = shutdown_signal();
    let timer = real_deadline(clock.clone(), deadline);
    tokio::pin!(shutdown, timer);
    let end_reason = loop {
        tokio::select! {
            biased;
            _ = &mut shutdown => break "signal",
            _ = &mut timer => break "duration",
            step = acq.step() => {
                if let Err(e) = step {
                    tracing::error!("hub fault: {e}");
                    faults.push(e.to_string());
                    break "fault";
                }
            }
        }
        let now = clock.now_us();
        if deadline.is_some_and(|d| now >= d) {
            break "duration";
        }
        progress.log(&acq, now);
    };
    let stats = acq.gate().stats();
    let report = RunReport {
        sensors: description.sensors,
        sets: stats.sets,
        set_rate_hz: stats.set_rate_hz(),
        spread_us_p99: stats.spread_us_p99(),
        faults,
        drops: stats.drops,
        sets_rejected: stats.sets_rejected,
        end_reason,
        transport: description.transport.clone(),
        trigger: description.trigger.as_str(),
        clock: match clock_arg {
            ClockArg::Real => "real",
            ClockArg::Virtual => "virtual",
        },
        elapsed_s: (clock.now_us() - start) as f64 / 1e6,
        max_spread_us: acq.gate().limits().max_spread_us,
        max_age_us: acq.gate().limits().max_age_us,
        set_latency_ms_p50: latency_ms(stats, 0.5),
        set_latency_ms_p99: latency_ms(stats, 0.99),
        frames_received: stats.frames_in,
        spread_histogram_us: stats.spread_buckets(),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", report.to_text());
    }
    Ok(if end_reason == "fault" { 1 } else { 0 })
}
