//! `gelgrip calibrate force` on a hardware hub: known weights placed on the sensor in turn.
//!
//! The sensor's frames come through the configured hub and gate, as in a run, and through
//! the sensor's configured gradient model (a model file: on hardware there is no simulated
//! camera to calibrate a LUT on). The user is prompted on stderr and confirms each step
//! with Enter on stdin: first the untouched sensor, whose frames become the pipeline's
//! reference and noise thresholds, then each weight of `--weights-g`, resting centred on
//! the pad through the user's indenter. Each reading is the mean indentation volume over
//! `--frames` frames, taken after the sets that were already on their way when Enter was
//! pressed. The fit is the simulator path's (`calibrate_force`), over the weights.
//!
//! Nothing is fitted unless every step completes: stdin closing, the hub going quiet or a
//! bad frame ends the command with an error naming the step.

use std::time::Duration;

use anyhow::Context;
use serde::Serialize;
use tokio::sync::mpsc;

use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::fusion::weight_force_n;
use gelgrip_plugins::config::PipelineConfig;
use gelgrip_plugins::pipeline::Needs;

use crate::cli::ForceArgs;
use crate::commands::calibrate_force::{Pair, WORST_CASE_FROM_N};
use gelgrip::wiring;
use gelgrip_controller::clock::ClockKind;

/// The report's group name for the weights.
pub const KNOWN_WEIGHTS: &str = "known weights";
/// Sets discarded after each Enter: those triggered before it (the acquisition keeps two
/// in flight) and one more for the gel to settle.
const SETTLE_SETS: usize = 3;
/// Longest wait for one synchronized set before the hub counts as gone.
const SET_TIMEOUT: Duration = Duration::from_secs(5);

/// One weight's reading.
#[derive(Debug, Clone, Serialize)]
pub struct WeightReading {
    /// The weight, g.
    pub weight_g: f64,
    /// Its load, N.
    pub force_n: f64,
    /// Mean indentation volume over the frames, mm³.
    pub volume_mm3: f64,
    /// Standard deviation of the frames' volumes, mm³.
    pub volume_sd_mm3: f64,
    /// Frames read.
    pub frames: usize,
    /// Frames in which the sensor saw contact.
    pub contact_frames: usize,
    /// The fitted proxy's error on this weight, % (None below 0.1 N, outside the fit).
    pub err_pct: Option<f64>,
}

impl WeightReading {
    /// The reading as a fit point.
    pub fn pair(&self) -> Pair {
        Pair {
            group: KNOWN_WEIGHTS.into(),
            volume_mm3: self.volume_mm3,
            force_n: self.force_n,
        }
    }

    /// The reading with its error under stiffness `k`, N/mm³.
    pub fn with_fit(mut self, k: f64) -> Self {
        self.err_pct = (self.force_n >= WORST_CASE_FROM_N).then(|| self.pair().err_pct(k));
        self
    }
}

/// Read every weight of `args` on sensor `index` through the configured hub.
pub async fn weigh(
    args: &ForceArgs,
    config: &AppConfig,
    pipeline: &PipelineConfig,
    index: usize,
) -> anyhow::Result<Vec<WeightReading>> {
    let id = args.sensor.as_str();
    let mut pipe = gelgrip::tactile::unreferenced_pipeline(config, pipeline, index)?;
    let registry = wiring::registry();
    let clock = ClockKind::Real.new_clock();
    let mut acq = wiring::open_acquisition(config, &registry, clock.clone())
        .await
        .with_context(|| format!("opening the {} hub", config.hub.transport))?;
    let mut enter = stdin_lines();
    let frames = args.frames as usize;
    let mut capture = Capture {
        acq: &mut acq,
        index,
        clock: clock.as_ref(),
    };

    eprintln!(
        "calibrate force on {id}: {} weights, {frames} frames each",
        args.weights_g.len()
    );
    capture
        .wait_for_enter(&mut enter, &format!("leave {id} untouched"))
        .await?;
    let quiet = capture
        .frames(frames)
        .await
        .context("the untouched sensor")?;
    let quiet: Vec<&[u8]> = quiet.iter().map(Vec::as_slice).collect();
    pipe.calibrate(&quiet)
        .with_context(|| format!("sensor {id}: reference frames"))?;

    let mut readings = Vec::with_capacity(args.weights_g.len());
    for &grams in &args.weights_g {
        let step = format!("place {grams} g on {id}, centred, and let it settle");
        capture.wait_for_enter(&mut enter, &step).await?;
        let jpegs = capture
            .frames(frames)
            .await
            .with_context(|| format!("{grams} g on {id}"))?;
        let mut volumes = Vec::with_capacity(jpegs.len());
        for jpeg in &jpegs {
            let summary = pipe
                .process(jpeg, Needs::DEPTH)
                .with_context(|| format!("{grams} g on {id}: a frame"))?;
            volumes.push((summary.in_contact, summary.volume_mm3.unwrap_or(0.0)));
        }
        let reading = reading(grams, &volumes);
        eprintln!(
            "  {grams} g ({:.3} N): volume {:.3} ± {:.3} mm³, contact in {} of {} frames",
            reading.force_n,
            reading.volume_mm3,
            reading.volume_sd_mm3,
            reading.contact_frames,
            reading.frames
        );
        if reading.contact_frames == 0 {
            tracing::warn!("{id} saw no contact under {grams} g: is the weight on the sensor?");
        }
        readings.push(reading);
    }
    eprintln!("done: lift the weight off {id}");
    Ok(readings)
}

/// One weight's reading from its frames' (contact, volume).
fn reading(grams: f64, volumes: &[(bool, f64)]) -> WeightReading {
    let n = volumes.len().max(1) as f64;
    let mean = volumes.iter().map(|(_, v)| v).sum::<f64>() / n;
    let var = volumes.iter().map(|(_, v)| (v - mean).powi(2)).sum::<f64>() / n;
    WeightReading {
        weight_g: grams,
        force_n: weight_force_n(grams),
        volume_mm3: mean,
        volume_sd_mm3: var.sqrt(),
        frames: volumes.len(),
        contact_frames: volumes.iter().filter(|(c, _)| *c).count(),
        err_pct: None,
    }
}

/// Stdin's lines, read on their own thread (a blocking read on the runtime's pool would
/// hold the runtime open at exit); the channel closes with stdin.
pub(crate) fn stdin_lines() -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel(4);
    std::thread::spawn(move || {
        use std::io::BufRead;
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if tx.blocking_send(line).is_err() {
                break;
            }
        }
    });
    rx
}

/// One sensor's frames from the acquisition.
struct Capture<'a> {
    acq: &'a mut Acquisition,
    index: usize,
    clock: &'a dyn gelgrip_controller::clock::Clock,
}

impl Capture<'_> {
    /// Prompt for `step` and wait for Enter, keeping the hub's sets flowing (and their
    /// errors surfacing) meanwhile.
    async fn wait_for_enter(
        &mut self,
        enter: &mut mpsc::Receiver<String>,
        step: &str,
    ) -> anyhow::Result<()> {
        eprintln!("> {step}, then press Enter");
        loop {
            tokio::select! {
                line = enter.recv() => {
                    return match line {
                        Some(_) => Ok(()),
                        None => Err(anyhow::anyhow!(
                            "stdin closed before the step `{step}` was confirmed: nothing was fitted"
                        )),
                    };
                }
                step = self.acq.step() => { step.context("the hub, between steps")?; }
            }
        }
    }

    /// `n` frames of the sensor from fresh sets (after [`SETTLE_SETS`]).
    async fn frames(&mut self, n: usize) -> anyhow::Result<Vec<Vec<u8>>> {
        let mut out = Vec::with_capacity(n);
        let mut skipped = 0;
        while out.len() < n {
            let deadline = self.clock.now_us() + SET_TIMEOUT.as_micros() as u64;
            let Some(set) = self.acq.next_set_before(deadline).await? else {
                let stats = self.acq.gate().stats();
                anyhow::bail!(
                    "no synchronized set from the hub in {} s ({} sets so far, gate: {stats:?})",
                    SET_TIMEOUT.as_secs(),
                    out.len() + skipped,
                );
            };
            if skipped < SETTLE_SETS {
                skipped += 1;
                continue;
            }
            let frame = set
                .frames
                .get(self.index)
                .context("a set without this sensor's frame")?;
            out.push(frame.frame.jpeg.to_vec());
        }
        Ok(out)
    }
}
