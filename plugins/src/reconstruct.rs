//! `gelgrip reconstruct`: the runtime's pipeline ([`SensorPipeline`]: contact window,
//! gradients, windowed Poisson solve, contact) applied to a user's own images with a model
//! file and a background image, each image giving full-size depth (mm, zero outside the
//! solved window), gradients and its contact.
//!
//! The pipeline's reference is the background itself. Its noise thresholds, which a live
//! run measures on its first untouched frames, are measured here on frames made from the
//! user's images ([`quiet_frame`]): each image with the blocks that differ from the
//! background beyond the image's own spread (median + [`QUIET_SPREADS`] × the scaled median
//! absolute deviation of the block activity), and [`QUIET_MARGIN_BLOCKS`] around them,
//! replaced by the background, so what is left is the camera's noise (as
//! `calibrate eval`'s windowed depth does with its labels, `calibrate::window`).

use thiserror::Error;

use crate::config::SensorStages;
use crate::contact::{BLOCK_PX, ContactSummary, DEFAULT_STIFFNESS_N_PER_MM3};
use crate::gradient::GradientModel;
use crate::image::RgbImage;
use crate::pipeline::{Needs, PipelineError, SensorPipeline, StageChoice};
use crate::poisson::Solver;

/// Images whose quiet frames calibrate the noise thresholds, at most (evenly spaced).
pub const QUIET_FRAMES: usize = 16;
/// A block is taken as touched when its activity exceeds the image's median block activity
/// by this many scaled median absolute deviations (a robust σ).
pub const QUIET_SPREADS: f64 = 5.0;
/// Blocks around a touched block also replaced by the background in a quiet frame.
pub const QUIET_MARGIN_BLOCKS: usize = 2;

/// Why a reconstruction could not be set up or an image not reconstructed.
#[derive(Debug, Error)]
pub enum ReconstructError {
    /// The background is not the size the model was trained at.
    #[error(
        "the background is {width}x{height} px but the model was trained at \
         {model_width}x{model_height} px"
    )]
    BackgroundSize {
        /// Background width, px.
        width: usize,
        /// Background height, px.
        height: usize,
        /// The model's width, px.
        model_width: usize,
        /// The model's height, px.
        model_height: usize,
    },
    /// An image of another size than the background (and the model).
    #[error(
        "{width}x{height} px, but the background and the model are {expected_width}x{expected_height} px"
    )]
    ImageSize {
        /// Image width, px.
        width: usize,
        /// Image height, px.
        height: usize,
        /// Background width, px.
        expected_width: usize,
        /// Background height, px.
        expected_height: usize,
    },
    /// A pixel size that is not a positive finite number.
    #[error("mm_per_px = {0}: expected a positive number")]
    PixelSize(f64),
    /// The pipeline failed.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
}

/// One image reconstructed, full size (`width × height`, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstruction {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Depth, mm, positive into the gel: the solved window's, zero outside it; finite.
    pub depth_mm: Vec<f32>,
    /// Gradients `(gx, gy)` per pixel interleaved (H×W×2, px per px), zero outside the
    /// window; finite.
    pub gradients: Vec<f32>,
    /// The contact stage's mask: pixels deeper than the noise threshold.
    pub contact: Vec<bool>,
    /// The contact stage's summary.
    pub summary: ContactSummary,
}

/// A reconstruction's figures as `gelgrip reconstruct --json` reports them: a value that
/// is missing or not finite reads 0, a centroid that is not finite none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactFigures {
    /// Anything in contact.
    pub in_contact: bool,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Deepest point, mm.
    pub max_depth_mm: f64,
    /// Indentation volume, mm³.
    pub volume_mm3: f64,
    /// Contact centroid `[x, y]`, px; none without contact.
    pub centroid_px: Option<[f64; 2]>,
}

impl Reconstruction {
    /// The contact's figures, as reported.
    pub fn figures(&self) -> ContactFigures {
        let finite = |v: Option<f64>| v.filter(|x| x.is_finite()).unwrap_or(0.0);
        let s = &self.summary;
        ContactFigures {
            in_contact: s.in_contact,
            area_mm2: finite(Some(s.area_mm2)),
            max_depth_mm: finite(s.max_depth_mm),
            volume_mm3: finite(s.volume_mm3),
            centroid_px: s
                .centroid_px
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|(x, y)| [x, y]),
        }
    }
}

/// Which of `n` images measure the noise thresholds: up to [`QUIET_FRAMES`] of them,
/// evenly spaced (indices into the `n`).
pub fn quiet_sample_indices(n: usize) -> Vec<usize> {
    let take = n.min(QUIET_FRAMES);
    (0..take).map(|k| k * n / take).collect()
}

/// A pipeline set up for one model, background, pixel size and solver.
#[derive(Debug)]
pub struct Reconstructor {
    pipe: SensorPipeline,
    width: usize,
    height: usize,
}

impl Reconstructor {
    /// A pipeline running `model` (an MLP in its own mode) on frames of `background`'s size
    /// of `mm_per_px`, with `solver`; the reference is `background`, the noise thresholds
    /// are measured on the [`quiet_frame`]s of `samples` (some of the images to come, of
    /// the background's size; the background alone when there are none).
    pub fn new(
        model: GradientModel,
        background: &RgbImage,
        samples: &[&RgbImage],
        mm_per_px: f64,
        solver: Solver,
    ) -> Result<Self, ReconstructError> {
        let (width, height) = (background.width, background.height);
        let (model_width, model_height) = model.size();
        if (model_width, model_height) != (width, height) {
            return Err(ReconstructError::BackgroundSize {
                width,
                height,
                model_width,
                model_height,
            });
        }
        if !(mm_per_px.is_finite() && mm_per_px > 0.0) {
            return Err(ReconstructError::PixelSize(mm_per_px));
        }
        let stages = SensorStages {
            decode_scale: 1,
            undistort: None,
            reference_alpha: 0.0,
            model: None,
            mlp: match &model {
                GradientModel::Lut(_) => None,
                GradientModel::Mlp { mode, .. } => Some(*mode),
            },
            solver: Some(solver),
            stiffness_n_per_mm3: DEFAULT_STIFFNESS_N_PER_MM3,
        };
        let choice = StageChoice { stages, model };
        let mut pipe = SensorPipeline::new(choice, width, height, mm_per_px);
        let quiet: Vec<Vec<u8>> = samples
            .iter()
            .filter(|s| (s.width, s.height) == (width, height))
            .map(|s| quiet_frame(s, background))
            .collect();
        let mut quiet_refs: Vec<&[u8]> = quiet.iter().map(Vec::as_slice).collect();
        if quiet_refs.is_empty() {
            quiet_refs.push(&background.data);
        }
        pipe.calibrate_rgb_against(&background.data, &quiet_refs)?;
        Ok(Self {
            pipe,
            width,
            height,
        })
    }

    /// The depth (mm) above which a pixel is in contact, as measured on the quiet frames.
    pub fn depth_threshold_mm(&self) -> Option<f32> {
        self.pipe.noise().map(|n| n.depth_threshold_mm)
    }

    /// Reconstruct one image (of the background's size).
    pub fn reconstruct(&mut self, image: &RgbImage) -> Result<Reconstruction, ReconstructError> {
        let (w, h) = (self.width, self.height);
        if (image.width, image.height) != (w, h) {
            return Err(ReconstructError::ImageSize {
                width: image.width,
                height: image.height,
                expected_width: w,
                expected_height: h,
            });
        }
        let summary = self.pipe.process_rgb(&image.data, Needs::DEPTH)?;
        let (depth, window) = self.pipe.last_depth_mm();
        let (gx, gy, _) = self.pipe.last_gradients();
        let (x0, y0, ww, wh) = window;
        let inside = ww.min(w.saturating_sub(x0));
        let mut depth_mm = vec![0.0f32; w * h];
        let mut gradients = vec![0.0f32; w * h * 2];
        for y in 0..wh.min(h.saturating_sub(y0)) {
            let (at, o) = (y * ww, (y0 + y) * w + x0);
            let depth_row = depth[at..].iter().take(inside);
            for (out, d) in depth_mm[o..o + inside].iter_mut().zip(depth_row) {
                *out = finite(*d);
            }
            let slopes = gx[at..].iter().zip(&gy[at..]).take(inside);
            for (out, (x, y)) in gradients[2 * o..2 * (o + inside)]
                .chunks_exact_mut(2)
                .zip(slopes)
            {
                out[0] = finite(*x);
                out[1] = finite(*y);
            }
        }
        let mut contact = Vec::new();
        self.pipe.last_contact_mask(&mut contact);
        Ok(Reconstruction {
            width: w,
            height: h,
            depth_mm,
            gradients,
            contact,
            summary,
        })
    }
}

/// A value, or 0 where it is not finite.
fn finite(v: f32) -> f32 {
    if v.is_finite() { v } else { 0.0 }
}

/// `image` with the blocks that differ from `background` beyond the image's own spread
/// (and [`QUIET_MARGIN_BLOCKS`] around them) replaced by the background: a frame with
/// nothing touching, whose noise elsewhere is the image's own (RGB8).
pub fn quiet_frame(image: &RgbImage, background: &RgbImage) -> Vec<u8> {
    let (w, h) = (image.width, image.height);
    let (bw, bh) = (w.div_ceil(BLOCK_PX), h.div_ceil(BLOCK_PX));
    let activity = block_activity(image, background);
    let threshold = robust_threshold(&activity);
    let mut out = image.data.clone();
    for (b, _) in activity.iter().enumerate().filter(|(_, a)| **a > threshold) {
        let (bx, by) = (b % bw, b / bw);
        let m = QUIET_MARGIN_BLOCKS;
        let xs = bx.saturating_sub(m) * BLOCK_PX..((bx + m + 1).min(bw) * BLOCK_PX).min(w);
        let ys = by.saturating_sub(m) * BLOCK_PX..((by + m + 1).min(bh) * BLOCK_PX).min(h);
        for y in ys {
            let row = (y * w + xs.start) * 3..(y * w + xs.end) * 3;
            out[row.clone()].copy_from_slice(&background.data[row]);
        }
    }
    out
}

/// Per [`BLOCK_PX`] block, the sum over channels of |mean of image − background| (the
/// pipeline's block activity).
fn block_activity(image: &RgbImage, background: &RgbImage) -> Vec<f64> {
    let (w, h) = (image.width, image.height);
    let (bw, bh) = (w.div_ceil(BLOCK_PX), h.div_ceil(BLOCK_PX));
    let mut sums = vec![[0.0f64; 3]; bw * bh];
    let mut counts = vec![0usize; bw * bh];
    for p in 0..w * h {
        let b = (p / w / BLOCK_PX) * bw + (p % w) / BLOCK_PX;
        let (frame, back) = (
            &image.data[3 * p..3 * p + 3],
            &background.data[3 * p..3 * p + 3],
        );
        for ((s, f), r) in sums[b].iter_mut().zip(frame).zip(back) {
            *s += f64::from(*f) - f64::from(*r);
        }
        counts[b] += 1;
    }
    sums.iter()
        .zip(&counts)
        .map(|(s, n)| s.iter().map(|v| (v / (*n).max(1) as f64).abs()).sum())
        .collect()
}

/// Median + [`QUIET_SPREADS`] × 1.4826 × the median absolute deviation of `v`.
fn robust_threshold(v: &[f64]) -> f64 {
    let median = |mut x: Vec<f64>| {
        x.sort_by(f64::total_cmp);
        x.get(x.len() / 2).copied().unwrap_or(0.0)
    };
    let m = median(v.to_vec());
    let mad = median(v.iter().map(|a| (a - m).abs()).collect());
    m + QUIET_SPREADS * 1.4826 * mad
}

/// Colour-map anchors (dark to bright: black, purple, red, orange, pale yellow), evenly
/// spaced over depth 0 to the image's deepest point.
const DEPTH_COLOURS: [[f32; 3]; 5] = [
    [0.0, 0.0, 4.0],
    [87.0, 16.0, 110.0],
    [188.0, 55.0, 84.0],
    [249.0, 142.0, 9.0],
    [252.0, 255.0, 164.0],
];
/// The contact's outline.
const OUTLINE_RGB: [u8; 3] = [0, 255, 255];

/// The depth as a colour map (0 and below black, the deepest point pale yellow) with the
/// contact's outline drawn over it.
pub fn depth_view(r: &Reconstruction) -> RgbImage {
    let (w, h) = (r.width, r.height);
    let peak = r.depth_mm.iter().copied().fold(0.0f32, f32::max);
    let mut img = RgbImage::new(w, h);
    for (p, d) in r.depth_mm.iter().enumerate() {
        let t = if peak > 0.0 {
            (d / peak).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let at = t * (DEPTH_COLOURS.len() - 1) as f32;
        let i = (at as usize).min(DEPTH_COLOURS.len() - 2);
        let f = at - i as f32;
        let (a, b) = (DEPTH_COLOURS[i], DEPTH_COLOURS[i + 1]);
        for c in 0..3 {
            img.data[3 * p + c] = (a[c] + (b[c] - a[c]) * f).round().clamp(0.0, 255.0) as u8;
        }
    }
    let inside = |x: usize, y: usize| r.contact.get(y * w + x).copied().unwrap_or(false);
    for y in 0..h {
        for x in 0..w {
            let edge = x == 0 || y == 0 || x + 1 == w || y + 1 == h;
            let rim = edge
                || !inside(x - 1, y)
                || !inside(x + 1, y)
                || !inside(x, y - 1)
                || !inside(x, y + 1);
            if inside(x, y) && rim {
                img.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&OUTLINE_RGB);
            }
        }
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quiet_frame_replaces_the_touched_blocks_and_keeps_the_noise() {
        let (w, h) = (64, 48);
        let background = RgbImage {
            width: w,
            height: h,
            data: vec![100; w * h * 3],
        };
        // Noise of ±1 everywhere, a bright patch at blocks (4, 3).
        let mut image = background.clone();
        for (i, v) in image.data.iter_mut().enumerate() {
            *v = if i % 7 < 3 { 101 } else { 99 };
        }
        for y in 24..32 {
            for x in 32..40 {
                image.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[180; 3]);
            }
        }
        let quiet = quiet_frame(&image, &background);
        // The patch and two blocks around it are the background; far away, the image.
        for (x, y) in [(35, 27), (16, 8 + 8), (55, 47)] {
            assert_eq!(quiet[3 * (y * w + x)], 100, "({x}, {y})");
        }
        assert_eq!(&quiet[..3 * w], &image.data[..3 * w]);
        assert_eq!(quiet.len(), image.data.len());
    }

    #[test]
    fn the_view_outlines_the_contact() {
        let (w, h) = (8, 6);
        let mut r = Reconstruction {
            width: w,
            height: h,
            depth_mm: vec![0.0; w * h],
            gradients: vec![0.0; w * h * 2],
            contact: vec![false; w * h],
            summary: ContactSummary::default(),
        };
        for y in 1..5 {
            for x in 2..6 {
                r.contact[y * w + x] = true;
                r.depth_mm[y * w + x] = 0.5;
            }
        }
        r.depth_mm[2 * w + 3] = 1.0;
        let img = depth_view(&r);
        let px = |x: usize, y: usize| &img.data[3 * (y * w + x)..3 * (y * w + x) + 3];
        assert_eq!(px(2, 1), OUTLINE_RGB);
        assert_eq!(px(5, 4), OUTLINE_RGB);
        assert_eq!(px(3, 2), [252, 255, 164]);
        assert_eq!(px(0, 0), [0, 0, 4]);
        // No contact, no depth: all black, no NaN from a zero peak.
        let blank = depth_view(&Reconstruction {
            contact: vec![false; w * h],
            depth_mm: vec![0.0; w * h],
            ..r
        });
        assert!(blank.data.chunks(3).all(|p| p == [0, 0, 4]));
    }
}
