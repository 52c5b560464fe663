//! `bench pipeline --markers`: what slip detection costs per frame. The first sensor's
//! press is timed through its pipeline twice, one frame at a time on one thread: on the
//! plain gel, and on the same gel with the marker layout's dots (pitch 1.2 mm, dots
//! 0.45 mm, as `layouts/three-finger-markers.toml`) moved by a tangential load that leaves
//! a stick ratio of 0.6 (so the stick ratio is fitted, the detector's dearest case). The
//! difference is what a marker gel costs; its parts are then timed apart on the same
//! decoded frames: the slip detection proper (the dots found and followed, the shear
//! fitted under the contact) and the dots' fill (what the depth needs of a marker gel).

use std::time::Instant;

use serde::Serialize;

use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::markers::MarkerGrid;
use gelgrip_plugins::config::SensorStages;
use gelgrip_plugins::decode::JpegStage;
use gelgrip_plugins::gradient::GradientModel;
use gelgrip_plugins::pipeline::{Needs, SensorPipeline, StageChoice};
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::markers::GelShear;
use gelgrip_sim::pool::{SceneCamera, SensorCamera};
use gelgrip_sim::traction::Traction;

/// The marker layout's grid.
const GRID: MarkerGrid = MarkerGrid {
    pitch_mm: 1.2,
    dot_mm: 0.45,
};
/// Frames rendered and cycled through, and frames timed.
const FRAMES: u64 = 8;
const TIMED: usize = 200;
/// The load's stick ratio.
const STICK_RATIO: f64 = 0.6;

/// The detector's cost, as `--json` prints it.
#[derive(Debug, Clone, Serialize)]
pub struct MarkerCost {
    /// The plain gel's frame, median ms.
    pub frame_ms_plain: f64,
    /// The marker gel's frame, median ms.
    pub frame_ms_markers: f64,
    /// Their difference: what a marker gel costs per frame, ms.
    pub marker_gel_ms_per_frame: f64,
    /// Slip detection per frame, ms: the frame's dots found and followed from the
    /// reference's, and the shear fitted under the contact (the next two).
    pub slip_detection_ms_per_frame: f64,
    /// The dots found in the frame and matched to the reference's, median ms.
    pub dot_tracking_ms: f64,
    /// The shear's pattern fitted under the contact, median ms.
    pub shear_fit_ms: f64,
    /// The dots filled from the gel around them (for the gradients and depth), median ms.
    pub dot_fill_ms: f64,
    /// Dots the pipeline found on the marker gel's reference.
    pub marker_dots: usize,
    /// Dots under the contact in the last frame.
    pub dots_inside: usize,
}

/// The median ms of processing `frames` (cycled) through `pipe`, after a warm-up.
fn frame_ms(pipe: &mut SensorPipeline, frames: &[Vec<u8>]) -> anyhow::Result<f64> {
    for f in frames {
        pipe.process(f, Needs::DEPTH)?;
    }
    let mut times = Vec::with_capacity(TIMED);
    for k in 0..TIMED {
        let t = Instant::now();
        pipe.process(&frames[k % frames.len()], Needs::DEPTH)?;
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

/// A ball's press at the pad's centre: diameter and depth, mm.
#[derive(Debug, Clone, Copy)]
pub struct Press {
    /// Ball diameter, mm.
    pub ball_mm: f64,
    /// Depth, mm.
    pub depth_mm: f64,
}

impl Press {
    /// Its contact radius, mm.
    fn contact_mm(self) -> f64 {
        let r = self.ball_mm / 2.0;
        (2.0 * r * self.depth_mm - self.depth_mm * self.depth_mm)
            .max(0.0)
            .sqrt()
    }
}

/// A referenced pipeline of `cam` with `stages` and `model`, and frames of `press` at the
/// pad's centre under `shear`.
fn pipeline_and_frames(
    cam: &SensorCamera,
    press: Press,
    stages: &SensorStages,
    model: &GradientModel,
    shear: Option<&GelShear>,
) -> anyhow::Result<(SensorPipeline, Vec<Vec<u8>>)> {
    let choice = StageChoice {
        stages: stages.clone(),
        model: model.clone(),
    };
    let mut pipe = SensorPipeline::new(choice, cam.width, cam.height, cam.mm_per_px);
    let quiet = cam.untouched_frames(3_000_000, 20)?;
    let quiet: Vec<&[u8]> = quiet.iter().map(Vec::as_slice).collect();
    pipe.calibrate(&quiet)?;
    let scene = SceneCamera::new(cam.clone());
    let centre = (cam.width as f64 / 2.0, cam.height as f64 / 2.0);
    let map = cam.ball_press_map(centre, press.ball_mm, press.depth_mm);
    let frames = (0..FRAMES)
        .map(|k| scene.jpeg(&map, shear, 4_000_000 + k))
        .collect::<Result<Vec<_>, _>>()?;
    Ok((pipe, frames))
}

/// The detector's cost on sensor 0 of `layout` under `sim` pressed by `press`, with
/// `stages` and `model`.
pub fn measure(
    layout: &HandLayout,
    sim: &SimConfig,
    press: Press,
    stages: &SensorStages,
    model: &GradientModel,
) -> anyhow::Result<MarkerCost> {
    let plain = SensorCamera::new(layout, 0, sim).ok_or_else(|| anyhow::anyhow!("no sensor"))?;
    let mut dotted_layout = layout.clone();
    for s in &mut dotted_layout.sensors {
        s.markers = Some(GRID);
    }
    let dotted =
        SensorCamera::new(&dotted_layout, 0, sim).ok_or_else(|| anyhow::anyhow!("no sensor"))?;
    let capacity_n = 1.0;
    let shear = GelShear {
        centre_px: (plain.width as f64 / 2.0, plain.height as f64 / 2.0),
        direction: (1.0, 0.0),
        traction: Traction::new(
            capacity_n,
            capacity_n * (1.0 - STICK_RATIO.powi(3)),
            capacity_n,
            press.contact_mm(),
        ),
    };
    let (mut p, frames) = pipeline_and_frames(&plain, press, stages, model, None)?;
    let frame_ms_plain = frame_ms(&mut p, &frames)?;
    let (mut m, frames) = pipeline_and_frames(&dotted, press, stages, model, Some(&shear))?;
    let frame_ms_markers = frame_ms(&mut m, &frames)?;
    let last = m.process(&frames[0], Needs::DEPTH)?;
    let parts = marker_parts(&mut m, &frames, stages.decode_scale.max(1))?;
    Ok(MarkerCost {
        frame_ms_plain,
        frame_ms_markers,
        marker_gel_ms_per_frame: frame_ms_markers - frame_ms_plain,
        slip_detection_ms_per_frame: parts.tracking_ms + parts.fit_ms,
        dot_tracking_ms: parts.tracking_ms,
        shear_fit_ms: parts.fit_ms,
        dot_fill_ms: parts.fill_ms,
        marker_dots: m.marker_dots().unwrap_or(0),
        dots_inside: last.shear.map_or(0, |e| e.dots_inside),
    })
}

/// A marker gel's stages timed apart, median ms per frame.
#[derive(Debug, Clone, Copy)]
struct MarkerParts {
    tracking_ms: f64,
    fit_ms: f64,
    fill_ms: f64,
}

/// Time the stages of `pipe`'s marker dots apart on `frames` decoded at `scale`, each
/// frame's contact as the pipeline reads it.
fn marker_parts(
    pipe: &mut SensorPipeline,
    frames: &[Vec<u8>],
    scale: usize,
) -> anyhow::Result<MarkerParts> {
    let mut ink = pipe
        .ink_fill()
        .cloned()
        .ok_or_else(|| anyhow::anyhow!("the marker gel's dots were not found"))?;
    let (w, h) = pipe.size();
    let mut decoder = JpegStage::new(w * scale, h * scale, scale);
    let mut decoded = Vec::with_capacity(frames.len());
    for f in frames {
        let mut rgb = vec![0u8; w * h * 3];
        decoder.decode(f, &mut rgb)?;
        let contact = pipe.process(f, Needs::DEPTH)?;
        decoded.push((rgb, contact));
    }
    let (mut tracking, mut fit, mut fill) = (Vec::new(), Vec::new(), Vec::new());
    let mut work = vec![0u8; w * h * 3];
    for k in 0..TIMED {
        let (rgb, contact) = &decoded[k % decoded.len()];
        work.copy_from_slice(rgb);
        let t = Instant::now();
        ink.follow(&work);
        tracking.push(t.elapsed());
        let t = Instant::now();
        ink.fill(&mut work);
        fill.push(t.elapsed());
        let t = Instant::now();
        std::hint::black_box(ink.shear_under(contact, pipe.mm_per_px(), scale as f64));
        fit.push(t.elapsed());
    }
    let median_ms = |mut v: Vec<std::time::Duration>| {
        v.sort();
        v[v.len() / 2].as_secs_f64() * 1e3
    };
    Ok(MarkerParts {
        tracking_ms: median_ms(tracking),
        fit_ms: median_ms(fit),
        fill_ms: median_ms(fill),
    })
}
