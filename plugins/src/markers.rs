//! Marker dots printed on a gel, found in the sensor's reference frame and filled in every
//! frame, so that the gradient and depth stages see the gel's shading alone (docs/pipeline.md,
//! "Marker gels").
//!
//! A marker gel's dots are dark prints that darken whatever light the gel returns. They are
//! found on the reference (no contact): per pixel, the brightness (the sum of the channels)
//! against the gel's brightness around it (the largest 3×3 mean within a window a few dots
//! wide). Those ratios fall in two groups, the gel's near 1 and the ink's well below; the
//! threshold between them comes from the reference itself (Otsu's split of the ratios'
//! histogram). A reference whose dark group is not a set of small dots of one size, enough
//! of them, is a plain gel and nothing is filled.
//!
//! In every frame (and the reference, loaded as a frame) a pixel darker than that share of
//! the reference's gel brightness there is ink, and so is every pixel within [`RIM_PX`] of
//! it (the dots' soft rims, a JPEG's ringing). The frame's dots are followed from the
//! reference's ([`DotTracker`]) before they are filled. Each ink pixel is
//! filled, per channel, from the gel pixels either side of it along its row and along its
//! column: the straight line between each pair, the two weighed by the inverse of their
//! spans (the shorter, nearer one counts more).
//! Contact shading changes the brightness far less than the ink does, so the test holds under
//! a press; a dot moved by the gel's shear is found where it is.

mod shear;
mod transmission;

pub use shear::{CONFIRM_FRAMES, DotTracker, ShearEstimate, SlipState};
use transmission::InkTransmission;

/// The gel's brightness is taken over a window of this share of the frame's shorter side.
const LEVEL_WINDOW_SHARE: f64 = 1.0 / 12.0;
/// The least dots that make a marker gel.
pub const MIN_DOTS: usize = 9;
/// A marker gel's dots cover at least this share of the frame, and at most the second.
const INK_SHARE_RANGE: (f64, f64) = (0.005, 0.4);
/// The dots' areas: the middle half lies within this factor of their median.
const DOT_AREA_SPREAD: f64 = 2.0;
/// Pixels this close to ink are filled too: the dots' soft rims, and the ringing a JPEG
/// leaves around a dark dot.
const RIM_PX: usize = 2;
/// The least dot, px.
const MIN_DOT_PX: usize = 4;

/// The marker dots of one sensor's gel, and how to fill them.
#[derive(Debug, Clone, PartialEq)]
pub struct InkFill {
    width: usize,
    height: usize,
    /// Per pixel, the gel's brightness around it in the reference, times the ink share.
    threshold: Vec<f32>,
    /// How many dots the reference showed.
    found: usize,
    /// The dots found whole on the reference, and each one's shift in the last frame.
    tracker: DotTracker,
    /// The ink's transmission around a whole dot's centre (`None`: every ink pixel is
    /// filled from the gel around it).
    transmission: Option<InkTransmission>,
    /// Working space of [`find_dots`].
    seen: Vec<bool>,
    stack: Vec<usize>,
    /// Working space: ink flags of the frame being filled, raw, widened along rows, and
    /// widened both ways.
    raw: Vec<u8>,
    wide: Vec<u8>,
    ink: Vec<bool>,
    /// Working space: per pixel, the fill along its row and that fill's weight.
    along_rows: Vec<([f32; 3], f32)>,
    /// Working space: per column, the row where its current run of ink began (or
    /// [`NO_RUN`]), and a running count of ink near each column.
    run_start: Vec<usize>,
    near_ink: Vec<u16>,
    /// Frames filled so far.
    frames: u64,
    /// The contact's estimated stick ratios of the last frames, for its state.
    confirmation: shear::Confirmation,
}

impl InkFill {
    /// The dots of the reference `rgb` (interleaved, `width × height`), or `None` for a
    /// plain gel.
    pub fn detect(rgb: &[f32], width: usize, height: usize) -> Option<Self> {
        if rgb.len() != width * height * 3 || width < 8 || height < 8 {
            return None;
        }
        let bright: Vec<f32> = rgb.chunks_exact(3).map(|p| p[0] + p[1] + p[2]).collect();
        let level = gel_level(&bright, width, height);
        let ratio: Vec<f32> = bright
            .iter()
            .zip(&level)
            .map(|(b, l)| if *l > 0.0 { b / l } else { 1.0 })
            .collect();
        let split = otsu_split(&ratio)?;
        let ink: Vec<bool> = ratio.iter().map(|r| *r < split).collect();
        let share = ink.iter().filter(|i| **i).count() as f64 / ink.len() as f64;
        if !(INK_SHARE_RANGE.0..=INK_SHARE_RANGE.1).contains(&share) {
            return None;
        }
        let (mut seen, mut stack) = (Vec::new(), Vec::new());
        let darkness = |p: usize| f64::from(split - ratio[p]);
        let dots = find_dots((width, height), |p| ink[p], darkness, &mut seen, &mut stack);
        if !is_marker_grid(&dots) {
            return None;
        }
        let threshold = level.iter().map(|l| l * split).collect();
        let mut fill = Self {
            width,
            height,
            threshold,
            found: dots.len(),
            tracker: DotTracker::new(whole_dots(&dots, width, height)),
            transmission: None,
            seen,
            stack,
            raw: vec![0; width * height],
            wide: vec![0; width * height],
            ink: vec![false; width * height],
            along_rows: vec![([0.0; 3], 0.0); width * height],
            run_start: vec![NO_RUN; width],
            near_ink: vec![0; width],
            frames: 0,
            confirmation: shear::Confirmation::default(),
        };
        fill.transmission = fill.measure_transmission(rgb);
        Some(fill)
    }

    /// The ink's transmission profile on `reference` (interleaved RGB, the size this fill
    /// was found on): the reference against its own line fill, around its whole dots.
    fn measure_transmission(&mut self, reference: &[f32]) -> Option<InkTransmission> {
        // Non-negative after the clamp: adding a half and truncating rounds it.
        let mut filled: Vec<u8> = reference
            .iter()
            .map(|v| (v.clamp(0.0, 255.0) + 0.5) as u8)
            .collect();
        self.mark(&filled);
        self.widen();
        self.fill_rows(&filled);
        self.fill_columns(&mut filled);
        let centres: Vec<(f64, f64)> = self.tracker.shifts().map(|(at, _)| at).collect();
        let size = (self.width, self.height);
        InkTransmission::measure(reference, &filled, size, &centres, self.tracker.pitch_px())
    }

    /// How far from a dot's centre its ink darkens the gel, px (`None`: no profile; every ink
    /// pixel is filled from the gel around it).
    pub fn ink_reach_px(&self) -> Option<f64> {
        self.transmission.as_ref().map(InkTransmission::reach_px)
    }

    /// How many dots the reference showed (those its border cuts among them; the whole
    /// ones are followed).
    pub fn dots(&self) -> usize {
        self.found
    }

    /// Count the last frame, one with nothing touching, towards the dots' noise: how far
    /// they were found from their reference places ([`DotTracker::learn_noise`]).
    pub fn learn_noise(&mut self) {
        self.tracker.learn_noise();
    }

    /// The shear the last frame's dots show under `contact` (its centroid in px of the
    /// full-resolution image, `scale` times the processed frame's), at `mm_per_px` of the
    /// processed frame: the contact taken as a disc of its area. Its state is confirmed
    /// over [`shear::CONFIRM_FRAMES`] frames: it is the stickiest of this frame's and the frames
    /// before's (a contact is said to slip once that many frames in a row show it; a frame
    /// or two of fits on noisy dots, or on a depth map whose contact flickered, do not);
    /// the stick ratio is this frame's.
    pub fn shear_under(
        &mut self,
        contact: &crate::contact::ContactSummary,
        mm_per_px: f64,
        scale: f64,
    ) -> Option<ShearEstimate> {
        let (cx, cy) = contact.centroid_px?;
        let radius_px = (contact.area_mm2 / std::f64::consts::PI).sqrt() / mm_per_px;
        // The centroid's pixel centres are at integers, the dots' at +0.5.
        let centre = ((cx + 0.5) / scale, (cy + 0.5) / scale);
        let mut estimate = self.tracker.estimate(centre, radius_px, mm_per_px);
        let confirmed = self
            .confirmation
            .confirm(self.frames, estimate.map(|e| e.stick_ratio));
        if let Some(e) = estimate.as_mut() {
            e.state = shear::state_of(confirmed);
        }
        estimate
    }

    /// Follow the dots of frame `rgb` (interleaved 8-bit, the reference's size), then fill
    /// its ink.
    pub fn fill_u8(&mut self, rgb: &mut [u8]) {
        if self.follow(rgb) {
            self.fill(rgb);
        }
    }

    /// Find the dots of frame `rgb` (interleaved 8-bit) and follow them from the
    /// reference's; false (nothing done) for a frame of another size than the reference.
    pub fn follow(&mut self, rgb: &[u8]) -> bool {
        if rgb.len() != self.threshold.len() * 3 {
            return false;
        }
        let brightness = |p: usize| {
            let v = &rgb[3 * p..3 * p + 3];
            f32::from(v[0]) + f32::from(v[1]) + f32::from(v[2])
        };
        self.mark(rgb);
        let (raw, threshold) = (&self.raw, &self.threshold);
        let frame_dots = find_dots(
            (self.width, self.height),
            |p| raw[p] != 0,
            |p| f64::from((threshold[p] - brightness(p)) / threshold[p].max(1.0)),
            &mut self.seen,
            &mut self.stack,
        );
        self.tracker.track(&frame_dots);
        self.frames += 1;
        true
    }

    /// Fill the ink that [`InkFill::follow`] found in the same frame `rgb`.
    pub fn fill(&mut self, rgb: &mut [u8]) {
        if rgb.len() != self.threshold.len() * 3 {
            return;
        }
        self.widen();
        if let Some(transmission) = &mut self.transmission {
            transmission.place(self.tracker.shifts(), self.tracker.noise_px());
            transmission.apply(rgb, &mut self.ink);
        }
        self.fill_rows(rgb);
        self.fill_columns(rgb);
    }

    /// Each ink pixel's fill along its row into `along_rows` (weight 0: none), from the gel
    /// pixels of `rgb` either side.
    fn fill_rows(&mut self, rgb: &[u8]) {
        let w = self.width;
        let value = |p: usize| [0, 1, 2].map(|c| f32::from(rgb[3 * p + c]));
        let fills = &mut self.along_rows;
        for (y, ink) in self.ink.chunks_exact(w).enumerate() {
            line_fill(ink, |k| y * w + k, &value, |p, f| fills[p] = f);
        }
    }

    /// Each ink pixel's fill along its column, blended with its fill along its row (each
    /// weighed by the inverse of its span), written into `rgb`. The rows are walked in
    /// order, each column's run of ink filled when the gel below it (or the frame's edge)
    /// ends it, so the frame is read row by row and only ink is written.
    fn fill_columns(&mut self, rgb: &mut [u8]) {
        let (w, h) = (self.width, self.height);
        for y in 0..=h {
            for x in 0..w {
                let ink = y < h && self.ink[y * w + x];
                let start = self.run_start[x];
                if ink {
                    if start == NO_RUN {
                        self.run_start[x] = y;
                    }
                } else if start != NO_RUN {
                    self.run_start[x] = NO_RUN;
                    fill_column_run(rgb, &self.along_rows, (w, h), x, start..y);
                }
            }
        }
    }

    /// Flag the ink of frame `rgb`: brightness (the channels' sum) under the threshold.
    fn mark(&mut self, rgb: &[u8]) {
        let pixels = rgb.chunks_exact(3).zip(&self.threshold);
        for (ink, (v, t)) in self.raw.iter_mut().zip(pixels) {
            let brightness = f32::from(v[0]) + f32::from(v[1]) + f32::from(v[2]);
            *ink = u8::from(brightness < *t);
        }
    }

    /// Flag what is filled: the ink and the pixels within [`RIM_PX`] of it.
    fn widen(&mut self) {
        let (w, r) = (self.width, RIM_PX);
        // Along rows, then along columns (each a running count of ink within r).
        for (row, out) in self.raw.chunks_exact(w).zip(self.wide.chunks_exact_mut(w)) {
            let mut count: u32 = row[..r.min(w)].iter().map(|v| u32::from(*v)).sum();
            for x in 0..w {
                if x + r < w {
                    count += u32::from(row[x + r]);
                }
                out[x] = u8::from(count > 0);
                if x >= r {
                    count -= u32::from(row[x - r]);
                }
            }
        }
        let h = self.height;
        let count = &mut self.near_ink;
        count.fill(0);
        for row in self.wide.chunks_exact(w).take(r) {
            count
                .iter_mut()
                .zip(row)
                .for_each(|(c, v)| *c += u16::from(*v));
        }
        for (y, out) in self.ink.chunks_exact_mut(w).enumerate() {
            if y + r < h {
                let row = &self.wide[(y + r) * w..(y + r + 1) * w];
                count
                    .iter_mut()
                    .zip(row)
                    .for_each(|(c, v)| *c += u16::from(*v));
            }
            out.iter_mut()
                .zip(count.iter())
                .for_each(|(o, c)| *o = *c > 0);
            if y >= r {
                let row = &self.wide[(y - r) * w..(y - r + 1) * w];
                count
                    .iter_mut()
                    .zip(row)
                    .for_each(|(c, v)| *c -= u16::from(*v));
            }
        }
    }
}

/// Along one line of pixels (`ink` flags; `at(k)` the `k`th's index): for each run of ink,
/// each pixel's straight-line fill between the gel pixels either side (the nearer one alone
/// at the line's end) and its weight (the inverse of the span; 0 when the line is all ink),
/// handed to `put(index, (fill, weight))`.
fn line_fill(
    ink: &[bool],
    at: impl Fn(usize) -> usize,
    value: &impl Fn(usize) -> [f32; 3],
    mut put: impl FnMut(usize, ([f32; 3], f32)),
) {
    let n = ink.len();
    let mut k = 0;
    while k < n {
        if !ink[k] {
            k += 1;
            continue;
        }
        let start = k;
        while k < n && ink[k] {
            k += 1;
        }
        let ends = (
            start.checked_sub(1).map(|l| (l, value(at(l)))),
            (k < n).then(|| (k, value(at(k)))),
        );
        for i in start..k {
            put(at(i), span_fill(ends, i));
        }
    }
}

/// The gel pixel before a run of ink and the one after it (where the line has them): their
/// place along the line and their value.
type RunEnds = (Option<(usize, [f32; 3])>, Option<(usize, [f32; 3])>);

/// The fill at `i` of a run of ink between `ends`: the straight line between them, weighed
/// by the inverse of their span (the nearer one alone, at half that weight, where the line
/// ends; nothing, weight 0, where it has neither).
fn span_fill(ends: RunEnds, i: usize) -> ([f32; 3], f32) {
    match ends {
        (Some((l, a)), Some((r, b))) => {
            let t = (i - l) as f32 / (r - l) as f32;
            (
                [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * t),
                1.0 / (r - l) as f32,
            )
        }
        (Some((e, v)), None) | (None, Some((e, v))) => (v, 0.5 / i.abs_diff(e) as f32),
        (None, None) => ([0.0; 3], 0.0),
    }
}

/// No run of ink has begun in this column.
const NO_RUN: usize = usize::MAX;

/// Fill the run of ink `rows` of column `x` of `rgb` (`w × h`): each pixel's straight-line
/// fill between the gel pixels above and below (the nearer one alone at the frame's edge),
/// weighed by the inverse of the span and blended with its fill along its row
/// (`along_rows`); a pixel neither line can fill is left.
fn fill_column_run(
    rgb: &mut [u8],
    along_rows: &[([f32; 3], f32)],
    (w, h): (usize, usize),
    x: usize,
    rows: std::ops::Range<usize>,
) {
    let value = |rgb: &[u8], y: usize| [0, 1, 2].map(|c| f32::from(rgb[3 * (y * w + x) + c]));
    let ends = (
        rows.start.checked_sub(1).map(|a| (a, value(rgb, a))),
        (rows.end < h).then(|| (rows.end, value(rgb, rows.end))),
    );
    for y in rows {
        let (f, wt) = span_fill(ends, y);
        let p = y * w + x;
        let (g, wg) = along_rows[p];
        let sum = wt + wg;
        if sum > 0.0 {
            let (wt, wg) = (wt / sum, wg / sum);
            for c in 0..3 {
                // Non-negative: adding a half and truncating rounds it.
                let blended = f[c] * wt + g[c] * wg;
                rgb[3 * p + c] = (blended + 0.5).clamp(0.0, 255.0) as u8;
            }
        }
    }
}

/// Per pixel, the gel's brightness around it: the largest 3×3 mean of `bright` within a
/// square window of [`LEVEL_WINDOW_SHARE`] of the shorter side.
fn gel_level(bright: &[f32], w: usize, h: usize) -> Vec<f32> {
    let smooth = box3(bright, w, h);
    let r = ((w.min(h) as f64 * LEVEL_WINDOW_SHARE / 2.0).round() as usize).max(2);
    let rows = running_max(&smooth, w, h, r, true);
    running_max(&rows, w, h, r, false)
}

/// A 3×3 mean (the edges over what is there).
fn box3(v: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0.0; v.len()];
    for y in 0..h {
        for x in 0..w {
            let (mut s, mut n) = (0.0, 0.0);
            for ny in y.saturating_sub(1)..(y + 2).min(h) {
                for nx in x.saturating_sub(1)..(x + 2).min(w) {
                    s += v[ny * w + nx];
                    n += 1.0;
                }
            }
            out[y * w + x] = s / n;
        }
    }
    out
}

/// The largest value within `r` along rows (`along_rows`) or columns.
fn running_max(v: &[f32], w: usize, h: usize, r: usize, along_rows: bool) -> Vec<f32> {
    let mut out = vec![0.0; v.len()];
    let (lines, len) = if along_rows { (h, w) } else { (w, h) };
    let at = |line: usize, i: usize| {
        if along_rows {
            line * w + i
        } else {
            i * w + line
        }
    };
    for line in 0..lines {
        for i in 0..len {
            let (lo, hi) = (i.saturating_sub(r), (i + r + 1).min(len));
            out[at(line, i)] = (lo..hi).map(|k| v[at(line, k)]).fold(f32::MIN, f32::max);
        }
    }
    out
}

/// Otsu's split of `values` (ratios, 0–~1.2) into a dark and a light group: the threshold
/// between them, `None` when they do not part (no dark group).
fn otsu_split(values: &[f32]) -> Option<f32> {
    const BINS: usize = 128;
    const TOP: f32 = 1.5;
    let mut hist = [0usize; BINS];
    for v in values.iter().filter(|v| v.is_finite()) {
        let b = ((v / TOP).clamp(0.0, 1.0) * (BINS - 1) as f32) as usize;
        hist[b] += 1;
    }
    let total: usize = hist.iter().sum();
    let sum_all: f64 = hist
        .iter()
        .enumerate()
        .map(|(b, n)| b as f64 * *n as f64)
        .sum();
    let (mut below, mut sum_below, mut best) = (0usize, 0.0, (0.0, 0));
    for (b, n) in hist.iter().enumerate() {
        below += n;
        sum_below += b as f64 * *n as f64;
        let above = total - below;
        if below == 0 || above == 0 {
            continue;
        }
        let (m0, m1) = (
            sum_below / below as f64,
            (sum_all - sum_below) / above as f64,
        );
        let between = below as f64 * above as f64 * (m1 - m0).powi(2);
        if between > best.0 {
            best = (between, b);
        }
    }
    let split = (best.1 as f32 + 0.5) / (BINS - 1) as f32 * TOP;
    // The dark group must be dark: well below the gel's own level.
    (best.0 > 0.0 && split < 0.8).then_some(split)
}

/// A dot of ink: its pixels, and its centre weighed by how dark each pixel is, px (pixel
/// centres at +0.5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dot {
    /// Pixels.
    pub area_px: usize,
    /// Centre `(x, y)`, px.
    pub centre_px: (f64, f64),
}

/// The 4-connected blobs of `is_ink` pixels of at least [`MIN_DOT_PX`], each centre
/// weighed by `weight`; `seen` and `stack` are working space.
fn find_dots(
    (w, h): (usize, usize),
    is_ink: impl Fn(usize) -> bool,
    weight: impl Fn(usize) -> f64,
    seen: &mut Vec<bool>,
    stack: &mut Vec<usize>,
) -> Vec<Dot> {
    seen.clear();
    seen.resize(w * h, false);
    let mut dots = Vec::new();
    for start in 0..w * h {
        if !is_ink(start) || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let (mut area, mut sum, mut sx, mut sy) = (0, 0.0, 0.0, 0.0);
        while let Some(p) = stack.pop() {
            let (x, y) = (p % w, p / w);
            let wt = weight(p).max(1e-6);
            (area, sum) = (area + 1, sum + wt);
            sx += wt * (x as f64 + 0.5);
            sy += wt * (y as f64 + 0.5);
            let near = [
                (x > 0).then(|| p - 1),
                (x + 1 < w).then(|| p + 1),
                (y > 0).then(|| p - w),
                (y + 1 < h).then(|| p + w),
            ];
            for q in near.into_iter().flatten() {
                if !seen[q] && is_ink(q) {
                    seen[q] = true;
                    stack.push(q);
                }
            }
        }
        if area >= MIN_DOT_PX && sum > 0.0 {
            dots.push(Dot {
                area_px: area,
                centre_px: (sx / sum, sy / sum),
            });
        }
    }
    dots
}

/// The centres of the `dots` that lie whole inside a `width × height` frame: a dot the
/// frame's border cuts shows only part of itself, whose centre moves wrongly as the gel
/// carries it in or out (its rim [`RIM_PX`] counts as the dot). The dots' radius is their
/// median area's.
fn whole_dots(dots: &[Dot], width: usize, height: usize) -> Vec<(f64, f64)> {
    let mut areas: Vec<usize> = dots.iter().map(|d| d.area_px).collect();
    areas.sort_unstable();
    let area = areas.get(areas.len() / 2).copied().unwrap_or(0) as f64;
    let margin = (area / std::f64::consts::PI).sqrt() + RIM_PX as f64;
    let inside = |v: f64, size: usize| v >= margin && v <= size as f64 - margin;
    dots.iter()
        .map(|d| d.centre_px)
        .filter(|&(x, y)| inside(x, width) && inside(y, height))
        .collect()
}

/// Whether `dots` are a marker grid's: at least [`MIN_DOTS`], the middle half of their
/// areas within [`DOT_AREA_SPREAD`] of the median.
fn is_marker_grid(dots: &[Dot]) -> bool {
    if dots.len() < MIN_DOTS {
        return false;
    }
    let mut areas: Vec<usize> = dots.iter().map(|d| d.area_px).collect();
    areas.sort_unstable();
    let median = areas[areas.len() / 2] as f64;
    let (q1, q3) = (
        areas[areas.len() / 4] as f64,
        areas[3 * areas.len() / 4] as f64,
    );
    q1 * DOT_AREA_SPREAD >= median && q3 <= DOT_AREA_SPREAD * median
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A gel of `level` with shading ramping across, dots of radius 3 px every 16 px
    /// darkened to a quarter (their edges anti-aliased), shifted by `dx`.
    fn gel(w: usize, h: usize, dots: bool, dx: f64) -> Vec<f32> {
        let mut rgb = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            for x in 0..w {
                let shade = 1.0 + 0.2 * x as f32 / w as f32;
                let (fx, fy) = (x as f64 + 0.5 - dx, y as f64 + 0.5);
                let (gx, gy) = ((fx / 16.0).round() * 16.0, (fy / 16.0).round() * 16.0);
                // The ink anti-aliased over the pixel around its edge, as a camera sees it.
                let cover = if dots {
                    (3.5 - (fx - gx).hypot(fy - gy)).clamp(0.0, 1.0) as f32
                } else {
                    0.0
                };
                let k = 1.0 - 0.75 * cover;
                rgb.extend([150.0, 140.0, 130.0].map(|c: f32| c * shade * k));
            }
        }
        rgb
    }

    #[test]
    fn a_marker_gel_is_found_and_filled_and_a_plain_gel_is_left_alone() {
        let (w, h) = (160, 120);
        assert_eq!(InkFill::detect(&gel(w, h, false, 0.0), w, h), None);
        let mut fill = InkFill::detect(&gel(w, h, true, 0.0), w, h).expect("a marker gel");
        assert!(fill.dots() >= 60, "{}", fill.dots());
        // A frame whose dots moved 5 px: filled, it is the plain gel within a grey level.
        let moved = gel(w, h, true, 5.0);
        let mut frame: Vec<u8> = moved.iter().map(|v| v.round() as u8).collect();
        fill.fill_u8(&mut frame);
        let plain = gel(w, h, false, 0.0);
        let worst = frame
            .iter()
            .zip(&plain)
            .map(|(a, b)| (f32::from(*a) - b).abs())
            .fold(0.0, f32::max);
        assert!(worst <= 2.0, "{worst}");
        // The reference, loaded as a frame, fills to the plain gel too.
        let mut reference: Vec<u8> = gel(w, h, true, 0.0)
            .iter()
            .map(|v| v.round() as u8)
            .collect();
        fill.fill_u8(&mut reference);
        let worst = reference
            .iter()
            .zip(&plain)
            .map(|(a, b)| (f32::from(*a) - b).abs())
            .fold(0.0, f32::max);
        assert!(worst <= 2.0, "{worst}");
    }

    #[test]
    fn dots_the_border_cuts_are_not_followed() {
        let dot = |x: f64, y: f64, area_px: usize| Dot {
            area_px,
            centre_px: (x, y),
        };
        // Dots of 28 px (radius 3 px, with the rim 5 px): one whole, three cut by the
        // border (a cut dot is smaller and its centre sits near the edge).
        let dots = [
            dot(50.0, 40.0, 28),
            dot(60.0, 40.0, 28),
            dot(2.0, 40.0, 12),
            dot(50.0, 78.5, 10),
            dot(96.0, 4.0, 28),
        ];
        assert_eq!(whole_dots(&dots, 100, 80), vec![(50.0, 40.0), (60.0, 40.0)]);
    }

    #[test]
    fn odd_frames_find_no_dots_and_fill_nothing() {
        assert_eq!(InkFill::detect(&[], 0, 0), None);
        assert_eq!(InkFill::detect(&vec![0.0; 64 * 64 * 3], 64, 64), None);
        assert_eq!(InkFill::detect(&vec![f32::NAN; 64 * 64 * 3], 64, 64), None);
        let mut fill = InkFill::detect(&gel(64, 64, true, 0.0), 64, 64).expect("dots");
        let mut wrong = vec![7u8; 10];
        fill.fill_u8(&mut wrong);
        assert_eq!(wrong, vec![7u8; 10]);
    }
}
