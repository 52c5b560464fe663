//! The per-sensor tactile pipeline: JPEG → (undistort) → difference against the reference →
//! gradients → depth → contact.
//!
//! Stages are chosen by name ([`StageChoice`]) and a stage runs only when something
//! downstream consumes it. If the caller needs only contact presence and area
//! ([`Needs::depth`] false), gradients and depth are skipped and contact comes from the
//! block activity alone. Depth is solved only over the bounding box of the active blocks
//! plus a margin, where the depth outside is zero (DST) or the window border is taken as
//! zero (DCT). All buffers are allocated up front; a solver plan is built the first time a
//! window size appears (sizes are rounded up to multiples of 16 px) and kept in a bounded
//! cache of the most recently used ([`crate::poisson::PlanCache`]): over a long hold a
//! contact's window passes through many sizes.

use thiserror::Error;

use crate::config::SensorStages;
use crate::contact::{self, BLOCK_PX, ContactSummary, NoiseModel};
use crate::decode::{DecodeError, JpegStage};
use crate::gradient::{GradientModel, MlpMode};
use crate::halves::{first_half, run_halves, worth_splitting};
use crate::lut::{Input, relative_gain};
use crate::markers::InkFill;
use crate::mlp::INPUTS;
use crate::model_file::{Slopes, to_forward_differences};
use crate::poisson::{PlanCache, Solver};
use crate::undistort::Remap;

mod activity;
mod calibration;
pub mod stream;
mod zero_level;

/// Registered stage names, per slot.
pub const STAGES: [(&str, &[&str]); 7] = [
    ("decode", &["jpeg"]),
    ("undistort", &["none", "fisheye"]),
    ("reference", &["static", "drift"]),
    ("diff", &["diff"]),
    ("gradient", &["lut", "mlp"]),
    ("depth", &["dst", "dct", "none"]),
    ("contact", &["threshold"]),
];

/// The stage choices for one sensor: its validated config and its loaded gradient model.
#[derive(Debug, Clone)]
pub struct StageChoice {
    /// Stage names and parameters (see [`crate::config`]).
    pub stages: SensorStages,
    /// The gradient model.
    pub model: GradientModel,
}

/// What the consumer reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Needs {
    /// Depth, volume and force (otherwise only presence and area).
    pub depth: bool,
    /// The gradients of the contact window ([`SensorPipeline::last_gradients`]), even
    /// with depth solver `none` (benchmarks that score them).
    pub gradients: bool,
}

impl Needs {
    /// Presence and area only.
    pub const AREA: Needs = Needs {
        depth: false,
        gradients: false,
    };
    /// Depth, volume and force.
    pub const DEPTH: Needs = Needs {
        depth: true,
        gradients: false,
    };
}

/// A frame the pipeline could not process.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum PipelineError {
    /// Decoding failed.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// The MLP gradient model failed to run (tensor allocation or shapes).
    #[error("gradient model: {0}")]
    Model(String),
    /// Asked to process before a reference frame was captured.
    #[error("no reference frame yet: capture one with nothing touching the sensor")]
    NoReference,
    /// A decoded frame of the wrong size.
    #[error("decoded frame of {bytes} bytes, expected {expected} (RGB8 at the processed size)")]
    FrameSize {
        /// Bytes given.
        bytes: usize,
        /// Bytes expected.
        expected: usize,
    },
}

/// A frame as the camera sends it (JPEG) or already decoded (RGB8 at the processed size).
#[derive(Clone, Copy)]
enum Frame<'a> {
    Jpeg(&'a [u8]),
    Rgb(&'a [u8]),
}

/// Contact-only MLP inference evaluates a pixel whose difference from the reference exceeds
/// this percentile of the no-contact frames' per-pixel differences. Lower evaluates more
/// pixels (slower); higher drops the shallow slopes of a contact (less accurate);
/// docs/calibration.md has the measured trade.
pub const PIXEL_NOISE_PERCENTILE: usize = 95;

/// A window of the image: `(x, y, width, height)` in px.
pub type Window = (usize, usize, usize, usize);

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
    /// `input = relative` only: each reference value's [`relative_gain`], so that a key
    /// costs no division.
    reference_gain: Vec<f32>,
    blocks: Vec<f32>,
    /// Working space of the block activity, per half (`halves`): one band of blocks' rows
    /// summed per column and channel (exact: integers).
    block_columns: [Vec<u16>; 2],
    /// Per block and channel, the sum of the reference's values (kept with the reference).
    reference_block_sums: Vec<[f64; 3]>,
    /// Blocks within one block of an active block: gradients outside them are set to 0.
    near_active: Vec<bool>,
    gx: Vec<f32>,
    gy: Vec<f32>,
    depth_px: Vec<f32>,
    plans: PlanCache<f32>,
    /// Working space for the depth anchor.
    scratch: Vec<f32>,
    noise: Option<NoiseModel>,
    last_window: (usize, usize, usize, usize),
    /// MLP only: the network's output for the background at each pixel (subtracted from
    /// every prediction, so a pixel like the background has zero gradient).
    background_prediction: Vec<[f32; 2]>,
    /// MLP contact-only: a pixel is evaluated when the sum over channels of
    /// |frame − reference| exceeds this (the no-contact frames' [`PIXEL_NOISE_PERCENTILE`]th percentile).
    pixel_threshold: f32,
    /// MLP: the rows evaluated and their window positions.
    features: Vec<f32>,
    feature_pixels: Vec<usize>,
    /// The last frame was solved for depth (its window holds depth in mm).
    last_has_depth: bool,
    /// A marker gel's dots, found on the reference and filled in every frame.
    ink: Option<InkFill>,
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
            reference_gain: Vec::new(),
            blocks: vec![0.0; bw * bh],
            block_columns: [Vec::with_capacity(w * 3), Vec::with_capacity(w * 3)],
            reference_block_sums: Vec::new(),
            near_active: vec![true; bw * bh],
            gx: vec![0.0; w * h],
            gy: vec![0.0; w * h],
            depth_px: vec![0.0; w * h],
            plans: PlanCache::default(),
            scratch: Vec::new(),
            noise: None,
            last_window: (0, 0, 0, 0),
            background_prediction: Vec::new(),
            pixel_threshold: 0.0,
            features: Vec::new(),
            feature_pixels: Vec::new(),
            last_has_depth: false,
            ink: None,
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

    /// Whether processing a frame may change the reference (`reference = "drift"`).
    pub fn updates_reference(&self) -> bool {
        self.choice.stages.reference_alpha > 0.0
    }

    /// The noise thresholds in force.
    pub fn noise(&self) -> Option<NoiseModel> {
        self.noise
    }

    fn load(&mut self, frame: Frame<'_>) -> Result<(), PipelineError> {
        self.load_unblurred(frame)?;
        // The model reads frames (and so the reference) through its blur.
        crate::image::box_blur_rgb(
            &mut self.rgb,
            self.width,
            self.height,
            self.choice.model.blur_px(),
        );
        Ok(())
    }

    /// [`Self::load`] but for the model's blur: decoded, undistorted, a marker gel's dots
    /// filled.
    fn load_unblurred(&mut self, frame: Frame<'_>) -> Result<(), PipelineError> {
        match frame {
            Frame::Jpeg(jpeg) => self.jpeg.decode(jpeg, &mut self.rgb)?,
            Frame::Rgb(rgb) => {
                if rgb.len() != self.rgb.len() {
                    return Err(PipelineError::FrameSize {
                        bytes: rgb.len(),
                        expected: self.rgb.len(),
                    });
                }
                self.rgb.copy_from_slice(rgb);
            }
        }
        if let Some(remap) = &self.remap {
            remap.apply(&self.rgb, &mut self.rgb_undistorted);
            std::mem::swap(&mut self.rgb, &mut self.rgb_undistorted);
        }
        // A marker gel's dots are not the gel's shading: filled before anything reads it.
        if let Some(ink) = &mut self.ink {
            ink.fill_u8(&mut self.rgb);
        }
        Ok(())
    }

    /// MLP: the network's output for the background key at every pixel.
    fn predict_background(&mut self) -> Result<(), PipelineError> {
        let GradientModel::Mlp { model, net, .. } = &self.choice.model else {
            return Ok(());
        };
        let Some(reference) = &self.reference else {
            return Ok(());
        };
        let (w, h) = (self.width, self.height);
        let s = self.choice.stages.decode_scale.max(1);
        let mut f = Vec::with_capacity(w * h * INPUTS);
        for p in 0..w * h {
            let key = match model.input {
                Input::Diff | Input::Relative => [0.0; 3],
                Input::Raw => [reference[p * 3], reference[p * 3 + 1], reference[p * 3 + 2]],
            };
            f.extend_from_slice(&model.features(key, (p % w) * s, (p / w) * s));
        }
        let out = net
            .forward(&f)
            .map_err(|e| PipelineError::Model(e.to_string()))?;
        self.background_prediction = out.chunks_exact(2).map(|g| [g[0], g[1]]).collect();
        Ok(())
    }

    /// Gradients over window `(x0, y0, w, h)` into `gx`, `gy` (window-sized, row-major).
    /// Pixels away from any active block get zero gradient: only the contact is integrated.
    fn window_gradients(
        &mut self,
        (x0, y0, w, h): (usize, usize, usize, usize),
    ) -> Result<(), PipelineError> {
        let width = self.width;
        let bw = self.width.div_ceil(BLOCK_PX);
        let Some(reference) = &self.reference else {
            return Ok(());
        };
        let input = self.choice.model.input();
        let key = |p: usize| match input {
            Input::Diff => [0, 1, 2].map(|c| f32::from(self.rgb[p * 3 + c]) - reference[p * 3 + c]),
            Input::Relative => [0, 1, 2].map(|c| {
                let i = p * 3 + c;
                (f32::from(self.rgb[i]) - reference[i]) * self.reference_gain[i]
            }),
            Input::Raw => [0, 1, 2].map(|c| f32::from(self.rgb[p * 3 + c])),
        };
        let near = |x: usize, y: usize| self.near_active[(y / BLOCK_PX) * bw + x / BLOCK_PX];
        // Models take positions at the full camera resolution they were trained at.
        let s = self.choice.stages.decode_scale.max(1);
        match &self.choice.model {
            GradientModel::Lut(lut) => {
                // Row by row, one block's run of pixels at a time: a run away from every
                // active block is zero at once. The rows in two halves (`halves`).
                let rows_from = |first: usize, gx: &mut [f32], gy: &mut [f32]| {
                    let rows = gx.chunks_exact_mut(w).zip(gy.chunks_exact_mut(w));
                    for (y, (gx_row, gy_row)) in (first..).zip(rows) {
                        let fy = y0 + y;
                        let mut x = 0;
                        while x < w {
                            let fx = x0 + x;
                            let run = (BLOCK_PX - fx % BLOCK_PX).min(w - x);
                            let gx_run = &mut gx_row[x..x + run];
                            let gy_run = &mut gy_row[x..x + run];
                            if near(fx, fy) {
                                let p = fy * width + fx;
                                let keys = &mut [[0.0f32; 3]; BLOCK_PX][..run];
                                for (k, key_k) in keys.iter_mut().enumerate() {
                                    *key_k = key(p + k);
                                }
                                lut.predict_run(keys, (fx * s, fy * s), s, gx_run, gy_run);
                            } else {
                                gx_run.fill(0.0);
                                gy_run.fill(0.0);
                            }
                            x += run;
                        }
                    }
                };
                let split = worth_splitting(w * h);
                let mid = first_half(h, 1, split);
                let (gx_a, gx_b) = self.gx[..w * h].split_at_mut(mid * w);
                let (gy_a, gy_b) = self.gy[..w * h].split_at_mut(mid * w);
                run_halves(
                    split,
                    || rows_from(0, gx_a, gy_a),
                    || rows_from(mid, gx_b, gy_b),
                );
            }
            GradientModel::Mlp { model, net, mode } => {
                self.features.clear();
                self.feature_pixels.clear();
                self.gx[..w * h].fill(0.0);
                self.gy[..w * h].fill(0.0);
                for y in 0..h {
                    for x in 0..w {
                        let (fx, fy) = (x0 + x, y0 + y);
                        let p = fy * width + fx;
                        let evaluate = match mode {
                            MlpMode::Dense => true,
                            MlpMode::ContactOnly => {
                                near(fx, fy)
                                    && pixel_difference(
                                        &self.rgb[p * 3..p * 3 + 3],
                                        &reference[p * 3..p * 3 + 3],
                                    ) > self.pixel_threshold
                            }
                        };
                        if evaluate {
                            self.features.extend_from_slice(&model.features(
                                key(p),
                                fx * s,
                                fy * s,
                            ));
                            self.feature_pixels.push(y * w + x);
                        }
                    }
                }
                let out = net
                    .forward(&self.features)
                    .map_err(|e| PipelineError::Model(e.to_string()))?;
                self.place_mlp_output(&out, (x0, y0, w));
            }
        }
        Ok(())
    }

    /// The network's output for the evaluated pixels (`feature_pixels`) of the window at
    /// `(x0, y0)`, `w` wide, less the background's prediction, into `gx`, `gy`.
    fn place_mlp_output(&mut self, out: &[f32], (x0, y0, w): (usize, usize, usize)) {
        let width = self.width;
        for (k, &q) in self.feature_pixels.iter().enumerate() {
            let (fx, fy) = (x0 + q % w, y0 + q / w);
            let bg = self
                .background_prediction
                .get(fy * width + fx)
                .copied()
                .unwrap_or([0.0; 2]);
            self.gx[q] = out[2 * k] - bg[0];
            self.gy[q] = out[2 * k + 1] - bg[1];
        }
    }

    /// Gradients and depth (px) over window `(x, y, w, h)`; returns the window's depth.
    /// `no_contact` marks the noise calibration's frames.
    fn solve_window(
        &mut self,
        (x0, y0, w, h): (usize, usize, usize, usize),
        no_contact: bool,
    ) -> Result<&[f32], PipelineError> {
        if self.reference.is_none() {
            return Ok(&[]);
        }
        self.window_gradients((x0, y0, w, h))?;
        if self.choice.model.slopes() == Slopes::Footprint {
            to_forward_differences(&mut self.gx[..w * h], &mut self.gy[..w * h], w);
        }
        let solver = self.choice.stages.solver.unwrap_or(Solver::Dst);
        let gradients = (&self.gx[..w * h], &self.gy[..w * h]);
        let depth = &mut self.depth_px[..w * h];
        self.plans.solve(solver, (h, w), gradients, depth);
        if solver == Solver::Dct {
            // Neumann leaves a free constant, and the gradients' bias a tilt: zero depth is
            // the plane through the window's sides inside the image (`zero_level`). When
            // the window spans the whole image the contact may cover all of it; depth is
            // never negative, so the shallowest pixels (2nd percentile) are zero. No-contact
            // frames (the noise calibration) take the whole border's mean level.
            let window = (x0, y0, w, h);
            let plane = if no_contact {
                Some(zero_level::border_level(depth, w, h))
            } else {
                zero_level::sides_plane(depth, window, (self.width, self.height))
            };
            match plane {
                Some(plane) => plane.subtract_from(depth, w),
                None => {
                    let zero = low_percentile(depth, &mut self.scratch);
                    depth.iter_mut().for_each(|d| *d -= zero);
                }
            }
        }
        self.last_window = (x0, y0, w, h);
        Ok(&self.depth_px[..w * h])
    }

    /// Process one frame.
    pub fn process(&mut self, jpeg: &[u8], needs: Needs) -> Result<ContactSummary, PipelineError> {
        self.process_frame(Frame::Jpeg(jpeg), needs)
    }

    /// [`SensorPipeline::process`] for a decoded frame (RGB8, `width × height` of
    /// [`SensorPipeline::size`]): the same window, gradients, depth and contact.
    pub fn process_rgb(
        &mut self,
        rgb: &[u8],
        needs: Needs,
    ) -> Result<ContactSummary, PipelineError> {
        self.process_frame(Frame::Rgb(rgb), needs)
    }

    fn process_frame(
        &mut self,
        frame: Frame<'_>,
        needs: Needs,
    ) -> Result<ContactSummary, PipelineError> {
        let noise = self.noise.ok_or(PipelineError::NoReference)?;
        self.last_has_depth = false;
        self.load(frame)?;
        self.block_activity();
        let window = self.active_window(noise.block_threshold);
        if window.is_none() && self.choice.stages.reference_alpha > 0.0 {
            self.refresh_reference();
        }
        let Some(window) = window else {
            self.last_window = (0, 0, 0, 0);
            return Ok(ContactSummary::default());
        };
        let scale = self.jpeg_scale();
        if needs.gradients && (!needs.depth || self.choice.stages.solver.is_none()) {
            self.mark_near_active(Some(noise.block_threshold));
            self.window_gradients(window)?;
            self.last_window = window;
        }
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
        self.solve_window(window, false)?;
        let (_, _, ww, wh) = self.last_window;
        let depth = &mut self.depth_px[..ww * wh];
        depth.iter_mut().for_each(|d| *d *= mm);
        self.last_has_depth = true;
        let mut summary = contact::summarize(
            depth,
            w,
            (x0, y0),
            self.mm_per_px,
            scale,
            &noise,
            self.choice.stages.stiffness_n_per_mm3,
        );
        if let Some(ink) = &mut self.ink {
            summary.shear = ink.shear_under(&summary, self.mm_per_px, scale);
        }
        Ok(summary)
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
        self.reference_changed();
    }

    /// Refresh what is kept with the reference: its gains and its block sums.
    fn reference_changed(&mut self) {
        self.refresh_reference_gain();
        self.refresh_reference_block_sums();
    }

    /// [`relative_gain`] of every reference value (`input = relative` only).
    fn refresh_reference_gain(&mut self) {
        self.reference_gain.clear();
        if let (Input::Relative, Some(reference)) = (self.choice.model.input(), &self.reference) {
            // relative_key(f, r) = (f − r) · relative_gain(r): the same key, bit for bit.
            self.reference_gain
                .extend(reference.iter().map(|r| relative_gain(*r)));
        }
    }

    /// Gradients (gx, gy; px per px) of the last window processed with depth or
    /// [`Needs::gradients`], and its `(x, y, w, h)`.
    pub fn last_gradients(&self) -> (&[f32], &[f32], Window) {
        let (_, _, w, h) = self.last_window;
        (&self.gx[..w * h], &self.gy[..w * h], self.last_window)
    }

    /// The last frame's contact mask over the whole (decoded) image: with depth, the pixels
    /// deeper than the noise threshold (the contact stage's own test); without, the pixels
    /// of blocks whose activity exceeds the noise.
    pub fn last_contact_mask(&self, out: &mut Vec<bool>) {
        let (w, h) = (self.width, self.height);
        out.clear();
        out.resize(w * h, false);
        let Some(noise) = self.noise else {
            return;
        };
        if self.last_has_depth {
            let (x0, y0, ww, wh) = self.last_window;
            for y in 0..wh {
                for x in 0..ww {
                    let d = self.depth_px[y * ww + x];
                    out[(y0 + y) * w + x0 + x] = d.is_finite() && d > noise.depth_threshold_mm;
                }
            }
        } else {
            let bw = w.div_ceil(BLOCK_PX);
            for (p, m) in out.iter_mut().enumerate() {
                *m = self.blocks[((p / w) / BLOCK_PX) * bw + (p % w) / BLOCK_PX]
                    > noise.block_threshold;
            }
        }
    }

    /// Depth (mm) of the last window processed with depth, and its `(x, y, w, h)`.
    pub fn last_depth_mm(&self) -> (&[f32], (usize, usize, usize, usize)) {
        let (_, _, w, h) = self.last_window;
        (&self.depth_px[..w * h], self.last_window)
    }
}

/// Process the frames of a set that has some sensors left out: frame `i`, where present,
/// through pipeline `i`, the sensors in parallel (rayon); `out[i]` is left as it was for a
/// sensor without a frame.
pub fn process_present(
    pipes: &mut [SensorPipeline],
    frames: &[Option<&[u8]>],
    needs: Needs,
    out: &mut [Result<ContactSummary, PipelineError>],
) {
    use rayon::prelude::*;
    pipes
        .par_iter_mut()
        .zip(frames.par_iter())
        .zip(out.par_iter_mut())
        .for_each(|((pipe, frame), slot)| {
            if let Some(frame) = frame {
                *slot = pipe.process(frame, needs);
            }
        });
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

/// Sum over channels of |frame − reference| at one pixel.
#[inline]
fn pixel_difference(rgb: &[u8], reference: &[f32]) -> f32 {
    rgb.iter()
        .zip(reference)
        .map(|(v, r)| (f32::from(*v) - r).abs())
        .sum()
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

#[cfg(test)]
mod tests;
