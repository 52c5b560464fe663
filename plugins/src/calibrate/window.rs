//! Depth as the runtime solves it: each press image through a [`SensorPipeline`] (its
//! contact window, gradients zeroed away from the active blocks, and its windowed Poisson
//! solve), scored inside the labelled contact (`calibrate eval`'s `window_depth_mae_mm`).
//!
//! The runtime calibrates its reference and noise thresholds on no-contact frames; a press
//! dataset holds one averaged background. The no-contact frames are therefore made from the
//! press images themselves, with the labelled contact and a margin around it
//! ([`QUIET_MARGIN_PX`] beyond 1.5 × its radius) replaced by the background: the camera
//! noise elsewhere is the presses' own.

use std::ops::Range;

use crate::calibrate::CalibrateError;
use crate::config::SensorStages;
use crate::contact::DEFAULT_STIFFNESS_N_PER_MM3;
use crate::dataset::{PressDataset, PressTruth};
use crate::gradient::GradientModel;
use crate::pipeline::{Needs, SensorPipeline, StageChoice};
use crate::poisson::Solver;

/// No-contact frames built for the pipeline's calibration (evenly spaced over the presses).
pub const QUIET_FRAMES: usize = 16;
/// Margin beyond 1.5 × the contact radius replaced by the background in a no-contact
/// frame, px.
pub const QUIET_MARGIN_PX: f64 = 16.0;

/// Windowed depth on some presses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowDepthReport {
    /// Mean |depth − truth| over the pixels inside the labelled contacts, mm; a pixel
    /// outside the solved window has depth 0 (as at runtime).
    pub depth_mae_mm: f64,
    /// Mean of the presses' true peak depths, mm (the scale `depth_mae_mm` compares to).
    pub mean_peak_depth_mm: f64,
    /// Presses in which the pipeline found no contact (all their depth read 0).
    pub missed_presses: usize,
    /// Presses evaluated.
    pub presses: usize,
    /// Inside pixels evaluated.
    pub pixels: usize,
}

/// Run `model` with depth solver `solver` through the runtime pipeline on `rows` of `ds`.
pub fn window_depth(
    model: &GradientModel,
    ds: &PressDataset,
    rows: Range<usize>,
    solver: Solver,
) -> Result<WindowDepthReport, CalibrateError> {
    let (w, h) = (ds.background.width, ds.background.height);
    let stages = SensorStages {
        decode_scale: 1,
        undistort: None,
        reference_alpha: 0.0,
        model: None,
        mlp: match model {
            GradientModel::Lut(_) => None,
            GradientModel::Mlp { mode, .. } => Some(*mode),
        },
        solver: Some(solver),
        stiffness_n_per_mm3: DEFAULT_STIFFNESS_N_PER_MM3,
    };
    let choice = StageChoice {
        stages,
        model: model.clone(),
    };
    let mut pipe = SensorPipeline::new(choice, w, h, ds.info.mm_per_px);
    let quiet = quiet_frames(ds)?;
    let quiet_refs: Vec<&[u8]> = quiet.iter().map(Vec::as_slice).collect();
    pipe.calibrate_rgb(&quiet_refs)?;

    let r = ds.ball_radius_px();
    let mm = ds.info.mm_per_px;
    let (mut err, mut peak, mut n, mut presses, mut missed) = (0.0, 0.0, 0usize, 0usize, 0usize);
    for press in ds.presses.get(rows).unwrap_or(&[]) {
        let img = ds.press_image(press)?;
        let truth = PressTruth::new(press, r, w, h);
        let summary = pipe.process_rgb(&img.data, Needs::DEPTH)?;
        let (depth_mm, (x0, y0, ww, wh)) = pipe.last_depth_mm();
        if !summary.in_contact || depth_mm.is_empty() {
            missed += 1;
        }
        let at = |p: usize| {
            let (x, y) = (p % w, p / w);
            let inside = x >= x0 && x < x0 + ww && y >= y0 && y < y0 + wh;
            let d = if inside {
                depth_mm
                    .get((y - y0) * ww + (x - x0))
                    .copied()
                    .unwrap_or(0.0)
            } else {
                0.0
            };
            if d.is_finite() { f64::from(d) } else { 0.0 }
        };
        for p in (0..w * h).filter(|p| truth.inside[*p]) {
            err += (at(p) - truth.depth_px[p] * mm).abs();
            n += 1;
        }
        peak += truth.depth_px.iter().copied().fold(0.0, f64::max) * mm;
        presses += 1;
    }
    Ok(WindowDepthReport {
        depth_mae_mm: err / n.max(1) as f64,
        mean_peak_depth_mm: peak / presses.max(1) as f64,
        missed_presses: missed,
        presses,
        pixels: n,
    })
}

/// Up to [`QUIET_FRAMES`] no-contact frames (RGB8): press images, evenly spaced over all
/// rows, with each contact and its margin replaced by the background; the background alone
/// when the dataset has no presses.
fn quiet_frames(ds: &PressDataset) -> Result<Vec<Vec<u8>>, CalibrateError> {
    let (w, h) = (ds.background.width, ds.background.height);
    let n = ds.presses.len();
    if n == 0 {
        return Ok(vec![ds.background.data.clone(); 2]);
    }
    let take = n.min(QUIET_FRAMES);
    let mut out = Vec::with_capacity(take);
    for k in 0..take {
        let press = &ds.presses[k * n / take];
        let mut img = ds.press_image(press)?.data;
        let reach = press.contact_radius_px * 1.5 + QUIET_MARGIN_PX;
        for y in 0..h {
            for x in 0..w {
                let dx = x as f64 - press.center_x_px;
                let dy = y as f64 - press.center_y_px;
                if dx * dx + dy * dy < reach * reach {
                    let p = (y * w + x) * 3;
                    img[p..p + 3].copy_from_slice(&ds.background.data[p..p + 3]);
                }
            }
        }
        out.push(img);
    }
    Ok(out)
}
