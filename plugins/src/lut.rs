//! Gradient model `lut`: binned colour → mean (Gx, Gy), the classic GelSight baseline.
//!
//! The key is the difference colour (frame − reference, each channel in −128…127), with
//! `input = relative` that difference relative to the reference ([`relative_key`]), or, with
//! `input = raw`, the raw colour (0…255), cut into `bins` bins per channel. Training
//! gives each bin the value that minimises the training loss over the labelled gradients
//! that fall in it ([`fit`]: the Huber estimate under `huber`, `calibrate train`'s default,
//! the median under `l1`, the mean under `l2`). Empty bins take the value of the nearest
//! filled bin (multi-source breadth-first fill over the 6-neighbour grid), so every colour
//! maps to a gradient. Lookup is one table read per pixel.
//!
//! A LUT may also be split into spatial tiles (`tiles = "tx,ty"`): one colour table per
//! tile, interpolated bilinearly between tile centres. Trained LUTs have one tile; an MLP
//! baked into a LUT ([`crate::mlp::bake`]) keeps its dependence on position that way.

use std::collections::VecDeque;
use std::path::Path;

use crate::mlp::train::Loss;
use crate::model_file::{self, ModelFile, ModelFileError, Slopes};

mod fit;

/// What the model's colour key is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// Frame minus reference, grey levels.
    Diff,
    /// Frame minus reference relative to the reference ([`relative_key`]): a gain that
    /// varies across the pad (vignetting, LED falloff) scales frame and reference alike
    /// and cancels, so one table reads a slope the same at the centre and at the edge.
    Relative,
    /// The raw frame.
    Raw,
}

impl Input {
    /// The names a model file's `input` takes.
    pub const NAMES: [&'static str; 3] = ["diff", "relative", "raw"];

    /// `diff`, `relative` or `raw`.
    pub fn as_str(self) -> &'static str {
        match self {
            Input::Diff => "diff",
            Input::Relative => "relative",
            Input::Raw => "raw",
        }
    }

    /// Parse `diff`, `relative` or `raw`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "diff" => Some(Input::Diff),
            "relative" => Some(Input::Relative),
            "raw" => Some(Input::Raw),
            _ => None,
        }
    }

    /// Whether the key is a difference from the reference (zero where nothing touches),
    /// as opposed to a raw colour.
    pub fn is_difference(self) -> bool {
        self != Input::Raw
    }

    /// The key of an untouched, mid-grey pixel: 0 for a difference, 128 for a raw colour
    /// (what a network's inputs are centred on).
    pub fn centre(self) -> f32 {
        if self.is_difference() { 0.0 } else { 128.0 }
    }
}

/// Grey level a reference channel is taken as at least, in [`relative_key`]: a channel
/// darker than that (a black or failed LED) would turn its noise into large keys.
pub const RELATIVE_FLOOR: f32 = 16.0;

/// The `relative` key of one channel: `(frame − reference) · 128 / max(reference,`
/// [`RELATIVE_FLOOR`]`)`, the difference as a share of the reference, in units of a
/// mid-grey reference's grey levels (so its range and binning are the difference's).
#[inline]
pub fn relative_key(frame: f32, reference: f32) -> f32 {
    (frame - reference) * relative_gain(reference)
}

/// [`relative_key`]'s multiplier for a reference value: `128 / max(reference,`
/// [`RELATIVE_FLOOR`]`)` (a pipeline keeps it per pixel, so a key costs no division).
#[inline]
pub fn relative_gain(reference: f32) -> f32 {
    128.0 / reference.max(RELATIVE_FLOOR)
}

/// Default bins per channel: 4 grey levels per bin of the difference.
pub const DEFAULT_BINS: usize = 64;

/// How a LUT is trained: its colour key, its bins per channel, and the loss each bin's
/// value minimises over the gradients that fall in it ([`fit`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LutSpec {
    /// The colour key.
    pub input: Input,
    /// Bins per channel.
    pub bins: usize,
    /// `l1`: each bin's median; `l2`: its mean; `huber`: between.
    pub loss: Loss,
    /// What the pixels on a press's rim teach.
    pub rim: RimPixels,
}

/// What the labelled pixels on a press's rim (within [`RIM_BAND_PX`], plus the frames' blur
/// radius, of its contact circle) teach a LUT. Such a pixel sees the cap's steepest facets
/// and the flat gel at once (and the camera's chroma is sampled over 2 × 2 pixels), so its
/// colour is neither's; where that colour is also a gentler facet's, a table that learns
/// the rim reads that facet as the rim's slope (docs/calibration.md, "The rim's pixels").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RimPixels {
    /// Every labelled pixel teaches its bin alike (the classic table).
    Learnt,
    /// A rim pixel teaches only a colour that no pixel off the rim showed, nor any within
    /// [`FALLBACK_BEYOND_BINS`] of one; the outside pixels the contact reaches into are
    /// labelled too (with the rise they cover), and a rim colour within the untouched
    /// gel's noise teaches nothing (that colour must read flat).
    Fallback,
}

/// Half-width of a press's rim band, px ([`RimPixels`]): a pixel's footprint reaches ½√2
/// px from its centre, and the camera's chroma is shared by 2 × 2 pixels.
pub const RIM_BAND_PX: f64 = 1.5;

/// How many bins (face steps) from a bin that pixels off the rim taught a rim-only colour
/// must be before the rim's value is used for it ([`LutTrainer::finish_with_fallback`]);
/// nearer, the neighbour's value is. A held-out press's gentle facets fall into the
/// training presses' sparse bins' gaps, and a gap the rim alone had reached read them the
/// rim's slope: on the realistic optics' bench (`bench label`, forward-difference labels)
/// 105 of 120 held-out presses within 10% of the ball's radius with 0, 116 with 1, 117
/// with 2 and 3; with the footprint labels 117 with 1 and 2.
pub const FALLBACK_BEYOND_BINS: usize = 2;

impl LutSpec {
    /// `calibrate train`'s LUT: the `relative` key, [`DEFAULT_BINS`], the `huber` loss, and
    /// the rim's pixels as a fallback.
    ///
    /// `relative`, because the LEDs' light falls off across the pad, and a difference
    /// scales with the light where it is taken (under any camera gamma, the ratio to the
    /// background does not): on the realistic optics' presses (`bench label`'s sphere
    /// check) the `diff` key leaves 58 of 120 held-out presses within 10% of the ball's
    /// radius, `relative` 95; on the real Mini the two agree (20 of 24, docs/calibration.md).
    ///
    /// [`RimPixels::Fallback`], because the rim's mixed colours otherwise teach other
    /// presses' gentle facets steep slopes: with the footprint labels, 89 → 117 of those
    /// 120 (nominal optics 119), and with both the real Mini's depth error 0.126 → 0.110
    /// mm (docs/calibration.md, "The rim's pixels").
    ///
    /// `huber`, robust as the median is where a colour is read from facets of two slopes,
    /// without the median's steps: a median bin is a sample's value, so the bins around the
    /// untouched colour sit at exactly zero and their neighbours jump to a contact's slope.
    /// Pixel noise crossing such a step reads as a spike of slope that the noise
    /// calibration, which saw zero, does not expect: with a median table, 15–25 of 300
    /// untouched frames of every simulated sensor showed a contact; with the Huber or the
    /// mean, none (docs/calibration.md, "Bin values").
    pub fn calibrate_default() -> Self {
        Self {
            input: Input::Relative,
            bins: DEFAULT_BINS,
            loss: Loss::Huber,
            rim: RimPixels::Fallback,
        }
    }

    /// The classic GelSight table of bin means (`l2`), on `input` with `bins` bins.
    pub fn means(input: Input, bins: usize) -> Self {
        Self {
            input,
            bins,
            loss: Loss::L2,
            rim: RimPixels::Learnt,
        }
    }
}

/// A trained lookup table.
#[derive(Debug, Clone, PartialEq)]
pub struct LutModel {
    /// Key kind.
    pub input: Input,
    /// Bins per channel.
    pub bins: usize,
    /// Image size it was trained at.
    pub width: usize,
    /// Image size it was trained at.
    pub height: usize,
    /// Per-channel offset added to the key before binning (zero-shot transfer).
    pub offset_rgb: [f32; 3],
    /// Spatial tiles `[across, down]` (`[1, 1]` for a trained LUT).
    pub tiles: [usize; 2],
    /// What it was made from: `presses` (trained) or `mlp` (baked).
    pub source: String,
    /// Box-blur radius applied to every frame and to the reference before the key is taken,
    /// px (0 = none; metadata `blur_px`): chosen at training from the sensor's measured
    /// pixel noise, since a table read through heavy noise learns gradients shrunk toward
    /// zero.
    pub blur_px: usize,
    /// Pixel size on the gel of the presses it was trained on, mm (metadata `mm_per_px`;
    /// `None` for a file written before it was recorded).
    pub mm_per_px: Option<f64>,
    /// Which slope a gradient in the table is (metadata `slopes`).
    pub slopes: Slopes,
    /// `tiles × bins³` entries of (gx, gy), tile-major.
    table: Vec<[f32; 2]>,
}

/// Accumulates labelled samples into bins.
#[derive(Debug, Clone)]
pub struct LutTrainer {
    input: Input,
    bins: usize,
    loss: Loss,
    /// Per bin, the gradients' sums (`l2`: the mean is all it needs).
    sums: Vec<[f64; 2]>,
    counts: Vec<u32>,
    /// Every sample as (bin, gradient), for the losses whose value is not a running sum:
    /// 12 bytes per labelled pixel (about 1.4 MB for the Mini's 22 training presses).
    samples: Vec<(u32, [f32; 2])>,
}

#[inline]
fn bin_of(v: f32, input: Input, bins: usize) -> usize {
    let unit = match input {
        Input::Diff | Input::Relative => (v + 128.0) / 256.0,
        Input::Raw => v / 256.0,
    };
    let b = (unit * bins as f32) as isize; // NaN → 0
    b.clamp(0, bins as isize - 1) as usize
}

#[inline]
fn index(rgb: [f32; 3], input: Input, bins: usize) -> usize {
    let [r, g, b] = rgb.map(|c| bin_of(c, input, bins));
    (r * bins + g) * bins + b
}

impl LutTrainer {
    /// An empty trainer whose bins take their samples' mean (the `l2` loss).
    pub fn new(input: Input, bins: usize) -> Self {
        Self::for_spec(LutSpec::means(input, bins))
    }

    /// An empty trainer for `spec`: its bins take the value that minimises its loss over
    /// their samples ([`fit`]).
    pub fn for_spec(spec: LutSpec) -> Self {
        let LutSpec {
            input, bins, loss, ..
        } = spec;
        let bins = bins.clamp(2, 256);
        let running = loss == Loss::L2;
        Self {
            input,
            bins,
            loss,
            sums: if running {
                vec![[0.0; 2]; bins * bins * bins]
            } else {
                Vec::new()
            },
            counts: vec![0; bins * bins * bins],
            samples: Vec::new(),
        }
    }

    /// Add one labelled pixel: its key colour and its gradient.
    pub fn add(&mut self, rgb: [f32; 3], gx: f32, gy: f32) {
        if !(gx.is_finite() && gy.is_finite()) {
            return;
        }
        let i = index(rgb, self.input, self.bins);
        if let Some(sum) = self.sums.get_mut(i) {
            sum[0] += f64::from(gx);
            sum[1] += f64::from(gy);
        } else {
            self.samples.push((i as u32, [gx, gy]));
        }
        self.counts[i] = self.counts[i].saturating_add(1);
    }

    /// Bins that received samples.
    pub fn filled_bins(&self) -> usize {
        self.counts.iter().filter(|c| **c > 0).count()
    }

    /// Fit each bin to its samples, fill the empty bins, and produce the model.
    pub fn finish(self, width: usize, height: usize) -> LutModel {
        let input = self.input;
        let (table, filled) = self.fitted_bins();
        model_of(input, table, filled, (width, height))
    }

    /// [`LutTrainer::finish`], where a bin that none of this trainer's samples reached, and
    /// none within [`FALLBACK_BEYOND_BINS`] of one, takes `fallback`'s value if any of its
    /// samples did (before the rest of the empty bins are filled from their neighbours).
    /// Both must have the same key and bins.
    pub fn finish_with_fallback(self, fallback: Self, width: usize, height: usize) -> LutModel {
        let (input, bins) = (self.input, self.bins);
        let (mut table, mut filled) = self.fitted_bins();
        if fallback.bins == bins && fallback.input == input {
            let (spare, spare_filled) = fallback.fitted_bins();
            grow(&mut table, &mut filled, FALLBACK_BEYOND_BINS);
            for i in 0..table.len() {
                if !filled[i] && spare_filled[i] {
                    table[i] = spare[i];
                    filled[i] = true;
                }
            }
        }
        model_of(input, table, filled, (width, height))
    }

    /// Each bin's fitted value, and whether any sample reached it.
    fn fitted_bins(mut self) -> (Vec<[f32; 2]>, Vec<bool>) {
        let n = self.bins;
        let mut table = vec![[0.0f32; 2]; n * n * n];
        for (i, (s, c)) in self.sums.iter().zip(&self.counts).enumerate() {
            if *c > 0 {
                table[i] = [(s[0] / f64::from(*c)) as f32, (s[1] / f64::from(*c)) as f32];
            }
        }
        fit::fit_bins(self.loss, &mut self.samples, |i, v| table[i] = v);
        let filled = self.counts.iter().map(|c| *c > 0).collect();
        (table, filled)
    }
}

/// Fill the empty bins next to filled ones with their values, `layers` layers deep
/// (breadth first over the 6 face neighbours; `usize::MAX`: until every bin is filled).
fn grow(table: &mut [[f32; 2]], filled: &mut [bool], layers: usize) {
    let n = (table.len() as f64).cbrt().round() as usize;
    let mut queue: VecDeque<(usize, usize)> = (0..n * n * n)
        .filter(|i| filled[*i])
        .map(|i| (i, 0))
        .collect();
    while let Some((i, layer)) = queue.pop_front() {
        if layer >= layers {
            continue;
        }
        let (r, g, b) = (i / (n * n), (i / n) % n, i % n);
        let neighbours = [
            (r > 0).then(|| i - n * n),
            (r + 1 < n).then(|| i + n * n),
            (g > 0).then(|| i - n),
            (g + 1 < n).then(|| i + n),
            (b > 0).then(|| i - 1),
            (b + 1 < n).then(|| i + 1),
        ];
        for j in neighbours.into_iter().flatten() {
            if !filled[j] {
                filled[j] = true;
                table[j] = table[i];
                queue.push_back((j, layer + 1));
            }
        }
    }
}

/// The model of a fitted `table` (bins³ entries) whose `filled` bins received samples: the
/// empty bins take the value of the nearest filled one (breadth first over the 6 face
/// neighbours).
fn model_of(
    input: Input,
    mut table: Vec<[f32; 2]>,
    mut filled: Vec<bool>,
    (width, height): (usize, usize),
) -> LutModel {
    let n = (table.len() as f64).cbrt().round() as usize;
    grow(&mut table, &mut filled, usize::MAX);
    LutModel {
        input,
        bins: n,
        width,
        height,
        offset_rgb: [0.0; 3],
        tiles: [1, 1],
        source: "presses".into(),
        blur_px: 0,
        mm_per_px: None,
        slopes: Slopes::Forward,
        table,
    }
}

/// Bin `i`'s centre value for a key kind (the colour a baked table is evaluated at).
pub fn bin_centre(i: usize, input: Input, bins: usize) -> f32 {
    let unit = (i as f32 + 0.5) / bins as f32;
    match input {
        Input::Diff | Input::Relative => unit * 256.0 - 128.0,
        Input::Raw => unit * 256.0,
    }
}

/// The pixel at the centre of tile `t` of `n` along an axis of `size` px (where a baked
/// table is evaluated, and where [`LutModel::predict_at`] returns it unblended).
pub fn tile_centre(t: usize, n: usize, size: usize) -> usize {
    ((t as f32 + 0.5) * size as f32 / n.max(1) as f32) as usize
}

impl LutModel {
    /// A LUT from a ready table of `tiles[0] × tiles[1] × bins³` entries (tile-major, then
    /// red, green, blue bins); `None` if the sizes disagree or a value is not finite.
    pub fn from_table(
        input: Input,
        bins: usize,
        (width, height): (usize, usize),
        tiles: [usize; 2],
        source: &str,
        table: Vec<[f32; 2]>,
    ) -> Option<Self> {
        let ok = (2..=256).contains(&bins)
            && tiles.iter().all(|t| (1..=64).contains(t))
            && table.len() == tiles[0] * tiles[1] * bins * bins * bins
            && table.iter().flatten().all(|v| v.is_finite());
        ok.then(|| Self {
            input,
            bins,
            width,
            height,
            offset_rgb: [0.0; 3],
            tiles,
            source: source.into(),
            blur_px: 0,
            mm_per_px: None,
            slopes: Slopes::Forward,
            table,
        })
    }

    #[inline]
    fn shifted(&self, rgb: [f32; 3]) -> usize {
        let key = [
            rgb[0] + self.offset_rgb[0],
            rgb[1] + self.offset_rgb[1],
            rgb[2] + self.offset_rgb[2],
        ];
        index(key, self.input, self.bins)
    }

    /// (gx, gy) for a key colour at pixel `(x, y)`: with tiles, interpolated bilinearly
    /// between the four nearest tile centres.
    #[inline]
    pub fn predict_at(&self, rgb: [f32; 3], x: usize, y: usize) -> [f32; 2] {
        let i = self.shifted(rgb);
        if self.tiles == [1, 1] {
            return self.table[i];
        }
        let cube = self.bins * self.bins * self.bins;
        let [tx, ty] = self.tiles;
        // Position in tile units, relative to the first tile's centre.
        let along = |p: usize, n: usize, size: usize| {
            let step = size.max(1) as f32 / n as f32;
            ((p as f32 - tile_centre(0, n, size) as f32) / step).clamp(0.0, (n - 1) as f32)
        };
        let (u, v) = (along(x, tx, self.width), along(y, ty, self.height));
        let (u0, v0) = (u as usize, v as usize);
        let (u1, v1) = ((u0 + 1).min(tx - 1), (v0 + 1).min(ty - 1));
        let (fu, fv) = (u - u0 as f32, v - v0 as f32);
        let at = |a: usize, b: usize| self.table[(b * tx + a) * cube + i];
        let (p00, p10, p01, p11) = (at(u0, v0), at(u1, v0), at(u0, v1), at(u1, v1));
        [0, 1].map(|c| {
            let top = p00[c] + (p10[c] - p00[c]) * fu;
            let bottom = p01[c] + (p11[c] - p01[c]) * fu;
            top + (bottom - top) * fv
        })
    }

    /// [`Self::predict_at`] for a run of pixels along a row, from `(x, y)` in steps of
    /// `step` px: `keys[k]`'s gradient into `gx[k]`, `gy[k]`.
    #[inline]
    pub fn predict_run(
        &self,
        keys: &[[f32; 3]],
        (x, y): (usize, usize),
        step: usize,
        gx: &mut [f32],
        gy: &mut [f32],
    ) {
        let out = gx.iter_mut().zip(gy.iter_mut());
        if self.tiles == [1, 1] {
            for (key, (gx, gy)) in keys.iter().zip(out) {
                [*gx, *gy] = self.table[self.shifted(*key)];
            }
            return;
        }
        for (k, (key, (gx, gy))) in keys.iter().zip(out).enumerate() {
            [*gx, *gy] = self.predict_at(*key, x + k * step, y);
        }
    }

    /// Save as a model file.
    pub fn save(&self, path: &Path) -> Result<(), ModelFileError> {
        let mut metadata = model_file::base_metadata(
            "lut",
            self.input.as_str(),
            (self.width, self.height),
            self.offset_rgb,
        );
        metadata.extend([
            ("bins".to_string(), self.bins.to_string()),
            (
                "tiles".to_string(),
                format!("{},{}", self.tiles[0], self.tiles[1]),
            ),
            ("source".to_string(), self.source.clone()),
            ("blur_px".to_string(), self.blur_px.to_string()),
        ]);
        model_file::put_mm_per_px(&mut metadata, self.mm_per_px);
        model_file::put_slopes(&mut metadata, self.slopes);
        let n = self.bins;
        let values = self.table.iter().flat_map(|g| *g).collect();
        let t = self.tiles[0] * self.tiles[1];
        ModelFile {
            metadata,
            tensors: vec![("lut".to_string(), vec![t, n, n, n, 2], values)],
        }
        .write(path)
    }

    /// Load a `kind = lut` model file.
    pub fn load(path: &Path) -> Result<Self, ModelFileError> {
        Self::from_file(&ModelFile::read(path)?, &path.display().to_string())
    }

    /// The LUT in an already read file (`p` names it in errors).
    pub fn from_file(file: &ModelFile, p: &str) -> Result<Self, ModelFileError> {
        let p = p.to_string();
        file.expect_key(&p, "kind", &["lut"])?;
        let input =
            Input::parse(file.expect_key(&p, "input", &Input::NAMES)?).unwrap_or(Input::Diff);
        let num = |key: &str| -> Result<usize, ModelFileError> {
            let v = file.expect_key(&p, key, &[])?;
            v.parse().map_err(|_| ModelFileError::Metadata {
                path: p.clone(),
                key: key.into(),
                actual: Some(v.into()),
                expected: "an integer".into(),
            })
        };
        let (width, height, bins) = (num("width")?, num("height")?, num("bins")?);
        if !(2..=256).contains(&bins) {
            return Err(ModelFileError::Metadata {
                path: p,
                key: "bins".into(),
                actual: Some(bins.to_string()),
                expected: "an integer in [2, 256]".into(),
            });
        }
        let offset_rgb = model_file::parse_rgb(file.metadata.get("offset_rgb").map(String::as_str))
            .ok_or_else(|| ModelFileError::Metadata {
                path: p.clone(),
                key: "offset_rgb".into(),
                actual: file.metadata.get("offset_rgb").cloned(),
                expected: "three comma-separated numbers".into(),
            })?;
        let tiles_text = file.metadata.get("tiles").map(String::as_str);
        let tiles = match tiles_text.map(|t| {
            t.split(',')
                .map(|v| {
                    v.trim()
                        .parse::<usize>()
                        .ok()
                        .filter(|n| (1..=64).contains(n))
                })
                .collect::<Option<Vec<_>>>()
        }) {
            None => [1, 1],
            Some(Some(v)) if v.len() == 2 => [v[0], v[1]],
            Some(_) => {
                return Err(ModelFileError::Metadata {
                    path: p,
                    key: "tiles".into(),
                    actual: tiles_text.map(str::to_string),
                    expected: "two integers in [1, 64], comma-separated".into(),
                });
            }
        };
        let t = tiles[0] * tiles[1];
        let Some((shape, values)) = file.tensor("lut") else {
            return Err(ModelFileError::Format {
                path: p,
                detail: "no tensor `lut`".into(),
            });
        };
        let shape_ok =
            shape == [t, bins, bins, bins, 2] || (t == 1 && shape == [bins, bins, bins, 2]);
        if !shape_ok || values.iter().any(|v| !v.is_finite()) {
            return Err(ModelFileError::Format {
                path: p,
                detail: format!(
                    "tensor `lut` has shape {shape:?} (expected [{t}, {bins}, {bins}, {bins}, 2]) or non-finite values"
                ),
            });
        }
        let table = values.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
        let source = file
            .metadata
            .get("source")
            .cloned()
            .unwrap_or_else(|| "presses".into());
        let mut model = Self::from_table(input, bins, (width, height), tiles, &source, table)
            .ok_or_else(|| ModelFileError::Format {
                path: p.clone(),
                detail: "table size disagrees with bins and tiles".into(),
            })?;
        model.offset_rgb = offset_rgb;
        model.blur_px = match file.metadata.get("blur_px") {
            None => 0,
            Some(v) => v
                .trim()
                .parse()
                .ok()
                .filter(|r| *r <= crate::image::MAX_BLUR_PX)
                .ok_or_else(|| ModelFileError::Metadata {
                    path: p.clone(),
                    key: "blur_px".into(),
                    actual: Some(v.clone()),
                    expected: format!("an integer in [0, {}]", crate::image::MAX_BLUR_PX),
                })?,
        };
        model.mm_per_px = model_file::mm_per_px(file, &p)?;
        model.slopes = model_file::slopes(file, &p)?;
        Ok(model)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_bins_and_fills_the_empty_ones() {
        let mut t = LutTrainer::new(Input::Diff, 8);
        t.add([0.0, 0.0, 0.0], 1.0, 2.0);
        t.add([1.0, 1.0, 1.0], 3.0, 4.0); // same bin
        t.add([100.0, -100.0, 0.0], -1.0, 0.5);
        assert_eq!(t.filled_bins(), 2);
        let m = t.finish(4, 4);
        assert_eq!(m.predict_at([0.5, 0.5, 0.5], 0, 0), [2.0, 3.0]);
        assert_eq!(m.predict_at([110.0, -110.0, 0.0], 0, 0), [-1.0, 0.5]);
        // An untouched colour takes its nearest filled bin.
        assert_eq!(m.predict_at([20.0, 10.0, 0.0], 0, 0), [2.0, 3.0]);
        assert!(
            m.predict_at([f32::NAN, 1e9, -1e9], 0, 0)
                .iter()
                .all(|v| v.is_finite())
        );
    }

    #[test]
    fn model_file_round_trips_and_names_bad_metadata() {
        let mut t = LutTrainer::new(Input::Raw, 4);
        t.add([10.0, 20.0, 30.0], 0.25, -0.5);
        let mut m = t.finish(320, 240);
        m.offset_rgb = [1.0, -2.0, 0.5];
        m.blur_px = 3;
        m.mm_per_px = Some(0.05);
        m.slopes = Slopes::Footprint;
        let dir = std::env::temp_dir().join(format!("gelgrip-lut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp dir");
        let path = dir.join("m.safetensors");
        m.save(&path).expect("save");
        assert_eq!(LutModel::load(&path).expect("load"), m);
        let mut unknown = m.clone();
        unknown.mm_per_px = None;
        unknown.save(&path).expect("save");
        assert_eq!(LutModel::load(&path).expect("load").mm_per_px, None);
        let mut forward = m.clone();
        forward.slopes = Slopes::Forward;
        forward.save(&path).expect("save");
        assert_eq!(LutModel::load(&path).expect("load").slopes, Slopes::Forward);
        let mut wide = m.clone();
        wide.blur_px = 99;
        wide.save(&path).expect("save");
        let err = LutModel::load(&path).expect_err("blur beyond the largest");
        assert!(err.to_string().contains("blur_px"), "{err}");
        let mut bad = m.clone();
        bad.bins = 0;
        bad.table.clear();
        bad.save(&path).expect("save");
        let err = LutModel::load(&path).expect_err("zero bins");
        assert!(err.to_string().contains("bins"), "{err}");
        std::fs::write(&path, b"not a model").expect("write");
        let err = LutModel::load(&path).expect_err("garbage");
        assert!(err.to_string().contains("m.safetensors"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
