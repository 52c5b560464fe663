//! `gelgrip bench dashboard [--clients 7] [--seconds 10] [--json]`: what serving the
//! dashboard costs. It starts `gelgrip run --http 127.0.0.1:0` (the default simulated
//! gripper, real clock), measures the process's CPU time over a window with no client,
//! then over a window with one MJPEG client per sensor (up to `--clients`) and one SSE
//! client, each counting what it receives. Wall-clock, on this host: CPU comes from
//! `/proc/<pid>/stat` (Linux).

use clap::Args;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use serde::Serialize;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

use crate::dashboard_child::DashboardChild;

/// The bench's result.
#[derive(Debug, Serialize)]
pub struct DashboardBench {
    /// MJPEG clients connected.
    pub mjpeg_clients: usize,
    /// Seconds per measuring window.
    pub seconds: f64,
    /// Frames per second each MJPEG client received (one per client).
    pub mjpeg_fps: Vec<f64>,
    /// The slowest client's rate.
    pub mjpeg_fps_min: f64,
    /// SSE events per second the SSE client received.
    pub sse_events_per_s: f64,
    /// Bytes per second all clients received together.
    pub bytes_per_s: f64,
    /// The process's CPU, % of one core, with no client.
    pub cpu_pct_idle: f64,
    /// The same with the clients.
    pub cpu_pct_clients: f64,
    /// What serving costs: the difference, % of one core.
    pub serving_cpu_pct: f64,
}

/// CPU seconds (user + system) of process `pid` so far.
fn cpu_s(pid: u32) -> anyhow::Result<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .context("reading /proc/<pid>/stat (this bench needs Linux)")?;
    // Fields after the parenthesised command name; utime and stime are the 14th and 15th.
    let rest = stat
        .rsplit_once(')')
        .map(|(_, r)| r)
        .context("malformed stat")?;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| -> anyhow::Result<f64> {
        Ok(fields.get(i).context("short stat")?.parse::<f64>()?)
    };
    // /proc reports clock ticks; USER_HZ is 100 on Linux.
    Ok((ticks(11)? + ticks(12)?) / 100.0)
}

async fn cpu_pct_over(pid: u32, seconds: f64) -> anyhow::Result<f64> {
    let (c0, t0) = (cpu_s(pid)?, Instant::now());
    tokio::time::sleep(Duration::from_secs_f64(seconds)).await;
    Ok(100.0 * (cpu_s(pid)? - c0) / t0.elapsed().as_secs_f64())
}

/// GET `path` from `addr` and count `marker` in what arrives (and the bytes) until the
/// deadline. The marker is searched across reads, so transfer chunking cannot hide one.
async fn count_stream(
    addr: String,
    path: String,
    marker: &'static [u8],
    until: Instant,
    count: Arc<AtomicU64>,
    bytes: Arc<AtomicU64>,
) -> anyhow::Result<()> {
    let mut s = tokio::net::TcpStream::connect(&addr).await?;
    s.write_all(
        format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").as_bytes(),
    )
    .await?;
    let mut buf = vec![0u8; 64 * 1024];
    let mut tail: Vec<u8> = Vec::new();
    while Instant::now() < until {
        let left = until.saturating_duration_since(Instant::now());
        let n = match tokio::time::timeout(left, s.read(&mut buf)).await {
            Ok(r) => r?,
            Err(_) => break,
        };
        if n == 0 {
            break;
        }
        bytes.fetch_add(n as u64, Ordering::Relaxed);
        tail.extend_from_slice(&buf[..n]);
        let found = tail.windows(marker.len()).filter(|w| *w == marker).count();
        count.fetch_add(found as u64, Ordering::Relaxed);
        let keep = tail.len().min(marker.len() - 1);
        tail.drain(..tail.len() - keep);
    }
    Ok(())
}

/// Run the bench; returns the exit code.
pub async fn run(args: BenchDashboardArgs) -> anyhow::Result<u8> {
    let mut run = DashboardChild::start(&[], false).await?;
    let result = measure(&args, run.pid(), run.addr.clone()).await;
    run.terminate();
    let _ = run.child.wait();
    let r = result?;
    if args.json {
        println!("{}", serde_json::to_string(&r)?);
    } else {
        println!(
            "dashboard with {} MJPEG clients and 1 SSE client, {} s windows:",
            r.mjpeg_clients, r.seconds
        );
        let fps: Vec<String> = r.mjpeg_fps.iter().map(|f| format!("{f:.1}")).collect();
        println!(
            "  MJPEG fps per client   {} (min {:.1})",
            fps.join(" "),
            r.mjpeg_fps_min
        );
        println!("  SSE events/s           {:.1}", r.sse_events_per_s);
        println!("  received               {:.2} MB/s", r.bytes_per_s / 1e6);
        println!(
            "  process CPU            {:.1}% idle, {:.1}% with clients: serving costs {:.1}% of one core",
            r.cpu_pct_idle, r.cpu_pct_clients, r.serving_cpu_pct
        );
    }
    Ok(0)
}

async fn measure(
    args: &BenchDashboardArgs,
    pid: u32,
    addr: String,
) -> anyhow::Result<DashboardBench> {
    let state: serde_json::Value = {
        // Wait for the first sets, then read the sensor ids.
        tokio::time::sleep(Duration::from_secs(2)).await;
        let mut s = tokio::net::TcpStream::connect(&addr).await?;
        s.write_all(
            format!("GET /api/state HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n")
                .as_bytes(),
        )
        .await?;
        let mut body = String::new();
        s.read_to_string(&mut body).await?;
        let json = body.split_once("\r\n\r\n").map(|(_, b)| b).unwrap_or("");
        serde_json::from_str(json).context("reading /api/state")?
    };
    let ids: Vec<String> = state["sensors"]
        .as_array()
        .context("no sensors in /api/state")?
        .iter()
        .filter_map(|s| s["id"].as_str().map(str::to_string))
        .take(args.clients)
        .collect();
    if ids.is_empty() {
        bail!("the run reports no sensors");
    }
    let seconds = args.seconds;
    eprintln!("measuring {seconds} s with no client…");
    let cpu_idle = cpu_pct_over(pid, seconds).await?;
    eprintln!(
        "measuring {seconds} s with {} MJPEG clients and 1 SSE client…",
        ids.len()
    );
    let warmup = Duration::from_secs(1);
    let until = Instant::now() + warmup + Duration::from_secs_f64(seconds);
    let bytes = Arc::new(AtomicU64::new(0));
    let mut counts = Vec::new();
    let mut tasks = Vec::new();
    for id in &ids {
        let c = Arc::new(AtomicU64::new(0));
        counts.push(c.clone());
        tasks.push(tokio::spawn(count_stream(
            addr.clone(),
            format!("/api/sensors/{id}/stream.mjpg"),
            b"--gelgripframe",
            until,
            c,
            bytes.clone(),
        )));
    }
    let sse = Arc::new(AtomicU64::new(0));
    tasks.push(tokio::spawn(count_stream(
        addr.clone(),
        "/api/events".into(),
        b"event: state",
        until,
        sse.clone(),
        bytes.clone(),
    )));
    tokio::time::sleep(warmup).await;
    let at_start: Vec<u64> = counts.iter().map(|c| c.load(Ordering::Relaxed)).collect();
    let (sse0, bytes0) = (sse.load(Ordering::Relaxed), bytes.load(Ordering::Relaxed));
    let cpu_clients = cpu_pct_over(pid, seconds).await?;
    let mjpeg_fps: Vec<f64> = counts
        .iter()
        .zip(&at_start)
        .map(|(c, s)| (c.load(Ordering::Relaxed) - s) as f64 / seconds)
        .collect();
    let sse_rate = (sse.load(Ordering::Relaxed) - sse0) as f64 / seconds;
    let bytes_rate = (bytes.load(Ordering::Relaxed) - bytes0) as f64 / seconds;
    for t in tasks {
        t.await??;
    }
    Ok(DashboardBench {
        mjpeg_clients: ids.len(),
        seconds,
        mjpeg_fps_min: mjpeg_fps.iter().copied().fold(f64::INFINITY, f64::min),
        mjpeg_fps,
        sse_events_per_s: sse_rate,
        bytes_per_s: bytes_rate,
        cpu_pct_idle: cpu_idle,
        cpu_pct_clients: cpu_clients,
        serving_cpu_pct: cpu_clients - cpu_idle,
    })
}

/// `gelgrip bench dashboard`.
#[derive(Debug, Args)]
pub struct BenchDashboardArgs {
    /// MJPEG clients, one per sensor (at most one per sensor).
    #[arg(long, default_value_t = 7)]
    pub clients: usize,
    /// Seconds per measuring window (one without clients, one with).
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}
