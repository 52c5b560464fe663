//! The per-sensor tactile pipeline: JPEG → (undistort) → difference against the reference →
//! gradients → depth → contact.
//!
//! Stages are chosen by name ([`StageChoice`]) and a stage runs only when something
//! downstream consumes it. If the caller needs only contact presence and area
//! ([`Needs::depth`] false), gradients and depth are skipped and contact comes from the
//! block activity alone. Depth is solved only over the bounding box of the active blocks
//! plus a margin, where the depth outside is zero (DST) or the window border is taken as
//! zero (DCT). All buffers are allocated up front; a solver plan is built the first time a
//! window size appears (sizes are rounded up to multiples of 16 px, so there are few).

use std::collections::HashMap;
use std::sync::Arc;

use thiserror::Error;

use crate::config::SensorStages;
use crate::contact::{self, BLOCK_PX, ContactSummary, NoiseModel};
use crate::decode::{DecodeError, JpegStage};
use crate::lut::{Input, LutModel};
use crate::poisson::{PoissonPlan, Solver};
use crate::undistort::Remap;

/// Registered stage names, per slot.
pub const STAGES: [(&str, &[&str]); 7] = [
    ("decode", &["jpeg"]),
    ("undistort", &["none", "fisheye"]),
    ("reference", &["static", "drift"]),
    ("diff", &["diff"]),
    ("gradient", &["lut"]),
    ("depth", &["dst", "dct", "none"]),
    ("contact", &["threshold"]),
];

/// The stage choices for one sensor: its validated config and its loaded gradient model.
#[derive(Debug, Clone)]
pub struct StageChoice {
    /// Stage names and parameters (see [`crate::config`]).
    pub stages: SensorStages,
    /// The gradient model.
    pub lut: Arc<LutModel>,
}

/// What the consumer reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Needs {
    /// Depth, volume and force (otherwise only presence and area).
    pub depth: bool,
}

/// A frame the pipeline could not process.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PipelineError {
    /// Decoding failed.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// Asked to process before a reference frame was captured.
    #[error("no reference frame yet: capture one with nothing touching the sensor")]
    NoReference,
}

/// Margin around the active blocks for the depth window, px (the depth must have fallen to
/// zero inside it; the blocks next to active ones are already integrated, so one block).
const WINDOW_MARGIN_PX: usize = 8;
/// Window sizes are multiples of this (DCT-II: N = k × 16) or one more (DST-I: its
/// interior has N + 1 = k × 16), so every transform has a smooth FFT size. Sizes with a
/// large prime factor, such as 97, 127 or 239, are several times slower.
const WINDOW_QUANTUM_PX: usize = 16;

/// One sensor's pipeline with its buffers.
pub struct SensorPipeline {
    choice: StageChoice,
    width: usize,
    height: usize,
    mm_per_px: f64,
    jpeg: JpegStage,
    remap: Option<Remap>,
    rgb: Vec<u8>,
    rgb_undistorted: Vec<u8>,
    reference: Option<Vec<f32>>,
    blocks: Vec<f32>,
    /// Blocks within one block of an active block: gradients outside them are set to 0.
    near_active: Vec<bool>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    depth_px: Vec<f32>,
    plans: HashMap<(usize, usize), PoissonPlan<f32>>,
    /// Working space for the depth anchor.
    scratch: Vec<f32>,
    noise: Option<NoiseModel>,
    last_window: (usize, usize, usize, usize),
}

impl std::fmt::Debug for SensorPipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorPipeline")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("solver", &self.choice.stages.solver)
            .field("noise", &self.noise)
            .finish()
    }
}

impl SensorPipeline {
    /// A pipeline for frames of `width × height` px of `mm_per_px`.
    pub fn new(choice: StageChoice, width: usize, height: usize, mm_per_px: f64) -> Self {
        let jpeg = JpegStage::new(width, height, choice.stages.decode_scale);
        let (w, h) = jpeg.output_size();
        let scale = (width / w.max(1)) as f64;
        let remap = choice
            .stages
            .undistort
            .as_ref()
            .map(|c| Remap::fisheye(c, w, h));
        let (bw, bh) = (w.div_ceil(BLOCK_PX), h.div_ceil(BLOCK_PX));
        Self {
            width: w,
            height: h,
            mm_per_px: mm_per_px * scale,
            jpeg,
            remap,
            rgb: vec![0; w * h * 3],
            rgb_undistorted: vec![0; w * h * 3],
            reference: None,
            blocks: vec![0.0; bw * bh],
            near_active: vec![true; bw * bh],
            gx: vec![0.0; w * h],
            gy: vec![0.0; w * h],
            depth_px: vec![0.0; w * h],
            plans: HashMap::new(),
            scratch: Vec::new(),
            noise: None,
            last_window: (0, 0, 0, 0),
            choice,
        }
    }

    /// Processed image size `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Pixel size after decode scaling, mm.
    pub fn mm_per_px(&self) -> f64 {
        self.mm_per_px
    }

    /// The noise thresholds in force.
    pub fn noise(&self) -> Option<NoiseModel> {
        self.noise
    }

    fn load(&mut self, jpeg: &[u8]) -> Result<(), PipelineError> {
        self.jpeg.decode(jpeg, &mut self.rgb)?;
        if let Some(remap) = &self.remap {
            remap.apply(&self.rgb, &mut self.rgb_undistorted);
            std::mem::swap(&mut self.rgb, &mut self.rgb_undistorted);
        }
        Ok(())
    }

    /// Capture the reference from no-contact frames (their mean), then measure the noise
    /// thresholds on the same frames.
    pub fn calibrate(&mut self, no_contact: &[&[u8]]) -> Result<(), PipelineError> {
        let mut sum = vec![0.0f32; self.rgb.len()];
        for jpeg in no_contact {
            self.load(jpeg)?;
            sum.iter_mut()
                .zip(&self.rgb)
                .for_each(|(s, v)| *s += f32::from(*v));
        }
        let n = no_contact.len().max(1) as f32;
        sum.iter_mut().for_each(|s| *s /= n);
        self.reference = Some(sum);
        let (mut activity, mut depth) = (Vec::new(), Vec::new());
        let window = self.central_window();
        let mm = self.mm_per_px as f32;
        for jpeg in no_contact {
            self.load(jpeg)?;
            self.block_activity();
            self.mark_near_active(None);
            activity.extend_from_slice(&self.blocks);
            if self.choice.stages.solver.is_some() {
                let d = self.solve_window(window, true);
                depth.extend(d.iter().map(|v| (v * mm).abs()));
            }
        }
        self.noise = Some(NoiseModel::measure(&activity, &depth));
        Ok(())
    }

    fn central_window(&self) -> (usize, usize, usize, usize) {
        let extra = usize::from(self.choice.stages.solver != Some(Solver::Dct));
        let w = (8 * WINDOW_QUANTUM_PX + extra).min(self.width);
        let h = (8 * WINDOW_QUANTUM_PX + extra).min(self.height);
        ((self.width - w) / 2, (self.height - h) / 2, w, h)
    }

    /// Per 8×8 block: the sum over channels of |mean(frame − reference)|, in one pass over
    /// the frame (the full difference image is never materialised).
    fn block_activity(&mut self) {
        let (w, h) = (self.width, self.height);
        let bw = w.div_ceil(BLOCK_PX);
        let Some(reference) = &self.reference else {
            return;
        };
        for by in 0..h.div_ceil(BLOCK_PX) {
            for bx in 0..bw {
                let mut sum = [0.0f32; 3];
                let (xs, xe) = (bx * BLOCK_PX, ((bx + 1) * BLOCK_PX).min(w));
                let ys = by * BLOCK_PX..((by + 1) * BLOCK_PX).min(h);
                let n = ((xe - xs) * ys.len()) as f32;
                for y in ys {
                    let row = &self.rgb[(y * w + xs) * 3..(y * w + xe) * 3];
                    let refs = &reference[(y * w + xs) * 3..(y * w + xe) * 3];
                    for (px, rf) in row.chunks_exact(3).zip(refs.chunks_exact(3)) {
                        sum[0] += f32::from(px[0]) - rf[0];
                        sum[1] += f32::from(px[1]) - rf[1];
                        sum[2] += f32::from(px[2]) - rf[2];
                    }
                }
                self.blocks[by * bw + bx] = sum.iter().map(|s| (s / n.max(1.0)).abs()).sum();
            }
        }
    }

    /// Bounding box `(x, y, w, h)` of active blocks plus the margin, rounded up.
    fn active_window(&self, threshold: f32) -> Option<(usize, usize, usize, usize)> {
        let bw = self.width.div_ceil(BLOCK_PX);
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for (k, a) in self.blocks.iter().enumerate() {
            if *a > threshold {
                let (bx, by) = (k % bw, k / bw);
                x0 = x0.min(bx * BLOCK_PX);
                y0 = y0.min(by * BLOCK_PX);
                x1 = x1.max((bx + 1) * BLOCK_PX);
                y1 = y1.max((by + 1) * BLOCK_PX);
            }
        }
        if x0 == usize::MAX {
            return None;
        }
        let extra = usize::from(self.choice.stages.solver != Some(Solver::Dct));
        let fit = |lo: usize, hi: usize, limit: usize| {
            let lo = lo.saturating_sub(WINDOW_MARGIN_PX);
            let hi = (hi + WINDOW_MARGIN_PX).min(limit);
            let len = (hi - lo).saturating_sub(extra).div_ceil(WINDOW_QUANTUM_PX)
                * WINDOW_QUANTUM_PX
                + extra;
            let len = len.min(limit);
            (lo.min(limit - len), len)
        };
        let (x, w) = fit(x0, x1, self.width);
        let (y, h) = fit(y0, y1, self.height);
        Some((x, y, w, h))
    }

    /// Mark blocks within one block of an active one (all blocks when `threshold` is None).
    fn mark_near_active(&mut self, threshold: Option<f32>) {
        let bw = self.width.div_ceil(BLOCK_PX);
        let bh = self.height.div_ceil(BLOCK_PX);
        let Some(t) = threshold else {
            self.near_active.fill(true);
            return;
        };
        self.near_active.fill(false);
        for by in 0..bh {
            for bx in 0..bw {
                if self.blocks[by * bw + bx] > t {
                    for ny in by.saturating_sub(1)..(by + 2).min(bh) {
                        for nx in bx.saturating_sub(1)..(bx + 2).min(bw) {
                            self.near_active[ny * bw + nx] = true;
                        }
                    }
                }
            }
        }
    }

    /// Gradients and depth (px) over window `(x, y, w, h)`; returns the window's depth.
    /// Pixels away from any active block get zero gradient: only the contact is integrated.
    /// `no_contact` marks the noise calibration's frames.
    fn solve_window(
        &mut self,
        (x0, y0, w, h): (usize, usize, usize, usize),
        no_contact: bool,
    ) -> &[f32] {
        let lut = &self.choice.lut;
        let width = self.width;
        let bw = self.width.div_ceil(BLOCK_PX);
        let Some(reference) = &self.reference else {
            return &[];
        };
        for y in 0..h {
            for x in 0..w {
                let p = (y0 + y) * width + x0 + x;
                if !self.near_active[((y0 + y) / BLOCK_PX) * bw + (x0 + x) / BLOCK_PX] {
                    self.gx[y * w + x] = 0.0;
                    self.gy[y * w + x] = 0.0;
                    continue;
                }
                let key = match lut.input {
                    Input::Diff => {
                        [0, 1, 2].map(|c| f32::from(self.rgb[p * 3 + c]) - reference[p * 3 + c])
                    }
                    Input::Raw => [
                        f32::from(self.rgb[p * 3]),
                        f32::from(self.rgb[p * 3 + 1]),
                        f32::from(self.rgb[p * 3 + 2]),
                    ],
                };
                let [gx, gy] = lut.predict(key);
                self.gx[y * w + x] = gx;
                self.gy[y * w + x] = gy;
            }
        }
        let solver = self.choice.stages.solver.unwrap_or(Solver::Dst);
        let plan = self
            .plans
            .entry((h, w))
            .or_insert_with(|| PoissonPlan::new(solver, h, w));
        let depth = &mut self.depth_px[..w * h];
        plan.solve(&self.gx[..w * h], &self.gy[..w * h], depth);
        if solver == Solver::Dct {
            // Neumann leaves a free constant. Zero depth is on the window's sides inside
            // the image (the margin around the contact); a side on the image edge may cut
            // through the contact (Neumann there is right, but its depth is not zero).
            // When the window spans the whole image the contact may cover all of it; depth
            // is never negative, so the shallowest pixels (2nd percentile) are zero.
            // No-contact frames (the noise calibration) take the whole border as zero.
            let window = (x0, y0, w, h);
            let zero = if no_contact {
                border_mean(depth, w, h)
            } else {
                interior_border_mean(depth, window, (self.width, self.height))
                    .unwrap_or_else(|| low_percentile(depth, &mut self.scratch))
            };
            depth.iter_mut().for_each(|d| *d -= zero);
        }
        self.last_window = (x0, y0, w, h);
        &self.depth_px[..w * h]
    }

    /// Process one frame.
    pub fn process(&mut self, jpeg: &[u8], needs: Needs) -> Result<ContactSummary, PipelineError> {
        let noise = self.noise.ok_or(PipelineError::NoReference)?;
        self.load(jpeg)?;
        self.block_activity();
        let window = self.active_window(noise.block_threshold);
        if window.is_none() && self.choice.stages.reference_alpha > 0.0 {
            self.refresh_reference();
        }
        let Some(window) = window else {
            return Ok(ContactSummary::default());
        };
        let scale = self.jpeg_scale();
        if !needs.depth || self.choice.stages.solver.is_none() {
            let active = self
                .blocks
                .iter()
                .filter(|a| **a > noise.block_threshold)
                .count();
            let block_mm = BLOCK_PX as f64 * self.mm_per_px;
            return Ok(ContactSummary {
                in_contact: true,
                area_mm2: active as f64 * block_mm * block_mm,
                ..Default::default()
            });
        }
        let (x0, y0, w, _) = window;
        let mm = self.mm_per_px as f32;
        self.mark_near_active(Some(noise.block_threshold));
        self.solve_window(window, false);
        let (_, _, ww, wh) = self.last_window;
        let depth = &mut self.depth_px[..ww * wh];
        depth.iter_mut().for_each(|d| *d *= mm);
        Ok(contact::summarize(
            depth,
            w,
            (x0, y0),
            self.mm_per_px,
            scale,
            &noise,
            self.choice.stages.stiffness_n_per_mm3,
        ))
    }

    fn jpeg_scale(&self) -> f64 {
        self.choice.stages.decode_scale.max(1) as f64
    }

    fn refresh_reference(&mut self) {
        let a = self.choice.stages.reference_alpha.clamp(0.0, 1.0);
        if let Some(reference) = &mut self.reference {
            for (r, v) in reference.iter_mut().zip(&self.rgb) {
                *r += a * (f32::from(*v) - *r);
            }
        }
    }

    /// Depth (mm) of the last window processed with depth, and its `(x, y, w, h)`.
    pub fn last_depth_mm(&self) -> (&[f32], (usize, usize, usize, usize)) {
        let (_, _, w, h) = self.last_window;
        (&self.depth_px[..w * h], self.last_window)
    }
}

/// Process one synchronized set: frame `i` through pipeline `i`, the sensors in parallel
/// (rayon), results into `out` (one per sensor).
pub fn process_set(
    pipes: &mut [SensorPipeline],
    frames: &[&[u8]],
    needs: Needs,
    out: &mut [Result<ContactSummary, PipelineError>],
) {
    use rayon::prelude::*;
    pipes
        .par_iter_mut()
        .zip(frames.par_iter())
        .zip(out.par_iter_mut())
        .for_each(|((pipe, frame), slot)| *slot = pipe.process(frame, needs));
}

/// The 2nd percentile of `d` (finite values), using `scratch`; 0 when none is finite.
fn low_percentile(d: &[f32], scratch: &mut Vec<f32>) -> f32 {
    scratch.clear();
    scratch.extend(d.iter().copied().filter(|v| v.is_finite()));
    if scratch.is_empty() {
        return 0.0;
    }
    let k = scratch.len() / 50;
    *scratch.select_nth_unstable_by(k, f32::total_cmp).1
}

/// Mean depth over the window's border pixels on the sides that lie inside the image (not
/// on its edge); `None` when the window spans the whole image.
fn interior_border_mean(
    d: &[f32],
    (x0, y0, w, h): (usize, usize, usize, usize),
    (width, height): (usize, usize),
) -> Option<f32> {
    let sides = [x0 > 0, x0 + w < width, y0 > 0, y0 + h < height];
    let (mut sum, mut n) = (0.0f64, 0usize);
    for y in 0..h {
        for x in 0..w {
            let on = [x == 0, x + 1 == w, y == 0, y + 1 == h];
            if on.iter().zip(&sides).any(|(o, s)| *o && *s) {
                sum += f64::from(d[y * w + x]);
                n += 1;
            }
        }
    }
    (n > 0).then(|| (sum / n as f64) as f32)
}

fn border_mean(d: &[f32], w: usize, h: usize) -> f32 {
    let mut sum = 0.0;
    let mut n = 0.0;
    for y in 0..h {
        for x in 0..w {
            if y == 0 || x == 0 || y + 1 == h || x + 1 == w {
                sum += d[y * w + x];
                n += 1.0;
            }
        }
    }
    if n > 0.0 { sum / n } else { 0.0 }
}

#[cfg(test)]
mod tests;
