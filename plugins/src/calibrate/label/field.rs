//! The difference field a contact is found in: the magnitude of (press − background), each
//! channel divided by the background's local level (the LEDs' falloff flattened), less its
//! median and box-blurred, with its noise level, its blobs above the noise and its rim along
//! rays.

use crate::image::RgbImage;

use super::{BACKGROUND_SMOOTH_PX, MIN_BLOB_PX, MIN_SIGNAL, RIM_FRACTION, SIGNAL_SIGMAS};

/// Step along a ray, px.
const RAY_STEP_PX: f64 = 0.5;

/// |press − background| per pixel, with the noise statistics of the frame.
#[derive(Debug, Clone)]
pub struct DiffField {
    width: usize,
    height: usize,
    magnitude: Vec<f32>,
    baseline: f64,
    spread: f64,
}

/// A 4-connected blob of pixels above the threshold.
#[derive(Debug, Clone)]
pub struct Blob {
    /// Its pixels (row-major indices).
    pub pixels: Vec<usize>,
    /// Centroid weighted by the magnitude above the threshold, px.
    pub centroid: (f64, f64),
    /// Its largest magnitude.
    pub peak: f64,
    /// Whether it reaches the image's first or last row or column.
    pub touches_border: bool,
}

impl DiffField {
    /// The field of `press` against `background` (same size), blurred with radius `blur_px`.
    ///
    /// A slope changes a pixel's brightness in proportion to the light falling there, and the
    /// LEDs light the pad unevenly (a real sensor's background falls off by half or more
    /// toward the corners). So each channel's difference is divided by the background's own
    /// level there (box-blurred over [`BACKGROUND_SMOOTH_PX`], at least 1) and scaled back by
    /// the channel's median level: grey levels as at a pixel of median brightness. An evenly
    /// lit background leaves the difference as it is.
    pub fn new(press: &RgbImage, background: &RgbImage, blur_px: usize) -> Self {
        let (w, h) = (press.width, press.height);
        let n = w * h;
        let mut channels: Vec<Vec<f32>> = (0..3)
            .map(|c| {
                let mut level: Vec<f32> = (0..n)
                    .map(|p| f32::from(background.data[3 * p + c]))
                    .collect();
                let reference = median(level.iter().step_by(7).copied().collect()).max(1.0) as f32;
                box_blur(&mut level, w, h, BACKGROUND_SMOOTH_PX);
                (0..n)
                    .map(|p| {
                        let d = f32::from(press.data[3 * p + c])
                            - f32::from(background.data[3 * p + c]);
                        d * reference / level[p].max(1.0)
                    })
                    .collect()
            })
            .collect();
        for ch in &mut channels {
            let shift = median(ch.iter().step_by(7).copied().collect()) as f32;
            ch.iter_mut().for_each(|v| *v -= shift);
            box_blur(ch, w, h, blur_px);
        }
        let magnitude: Vec<f32> = (0..n)
            .map(|p| (channels.iter().map(|c| c[p] * c[p]).sum::<f32>()).sqrt())
            .collect();
        let sample: Vec<f32> = magnitude.iter().step_by(3).copied().collect();
        let baseline = median(sample.clone());
        let spread = 1.4826
            * median(
                sample
                    .iter()
                    .map(|v| (f64::from(*v) - baseline).abs() as f32)
                    .collect(),
            );
        Self {
            width: w,
            height: h,
            magnitude,
            baseline,
            spread,
        }
    }

    /// The magnitude of untouched gel (the frame's median), grey levels.
    pub fn baseline(&self) -> f64 {
        self.baseline
    }

    /// The magnitude above which a pixel is signal: [`SIGNAL_SIGMAS`] noise spreads above
    /// the baseline, and at least [`MIN_SIGNAL`] above it.
    pub fn threshold(&self) -> f64 {
        self.baseline + (SIGNAL_SIGMAS * self.spread).max(MIN_SIGNAL)
    }

    /// Blobs above `threshold` of at least [`MIN_BLOB_PX`] pixels, largest first.
    pub fn blobs(&self, threshold: f64) -> Vec<Blob> {
        let (w, h) = (self.width, self.height);
        let above: Vec<bool> = self
            .magnitude
            .iter()
            .map(|v| f64::from(*v) > threshold)
            .collect();
        let mut seen = vec![false; w * h];
        let mut blobs = Vec::new();
        for start in 0..w * h {
            if !above[start] || seen[start] {
                continue;
            }
            seen[start] = true;
            let mut stack = vec![start];
            let mut pixels = Vec::new();
            while let Some(p) = stack.pop() {
                pixels.push(p);
                let (x, y) = (p % w, p / w);
                let mut push = |q: usize| {
                    if above[q] && !seen[q] {
                        seen[q] = true;
                        stack.push(q);
                    }
                };
                if x > 0 {
                    push(p - 1);
                }
                if x + 1 < w {
                    push(p + 1);
                }
                if y > 0 {
                    push(p - w);
                }
                if y + 1 < h {
                    push(p + w);
                }
            }
            if pixels.len() >= MIN_BLOB_PX {
                blobs.push(self.blob(pixels, threshold));
            }
        }
        blobs.sort_by_key(|b| std::cmp::Reverse(b.pixels.len()));
        blobs
    }

    fn blob(&self, pixels: Vec<usize>, threshold: f64) -> Blob {
        let w = self.width;
        let (mut sw, mut sx, mut sy, mut peak) = (0.0, 0.0, 0.0, 0.0f64);
        let mut touches_border = false;
        for &p in &pixels {
            let (x, y) = (p % w, p / w);
            touches_border |= x == 0 || y == 0 || x + 1 == w || y + 1 == self.height;
            let m = f64::from(self.magnitude[p]);
            let wgt = m - threshold;
            sw += wgt;
            sx += wgt * x as f64;
            sy += wgt * y as f64;
            peak = peak.max(m);
        }
        let centroid = if sw > 0.0 {
            (sx / sw, sy / sw)
        } else {
            let p = pixels[0];
            ((p % w) as f64, (p / w) as f64)
        };
        Blob {
            pixels,
            centroid,
            peak,
            touches_border,
        }
    }

    /// Share of `pixels` where a channel of `press` is clipped (0 or 255) and the
    /// background's is not.
    pub fn clipped_share(&self, press: &RgbImage, background: &RgbImage, pixels: &[usize]) -> f64 {
        if pixels.is_empty() {
            return 0.0;
        }
        let clipped = pixels
            .iter()
            .filter(|&&p| {
                (0..3).any(|c| {
                    let (v, b) = (press.data[3 * p + c], background.data[3 * p + c]);
                    (v == 0 || v == 255) && v != b
                })
            })
            .count();
        clipped as f64 / pixels.len() as f64
    }

    /// Bilinear magnitude at (`x`, `y`); `None` outside the image.
    fn at(&self, x: f64, y: f64) -> Option<f64> {
        let (w, h) = (self.width, self.height);
        if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let m = |x: usize, y: usize| f64::from(self.magnitude[y * w + x]);
        let top = m(x0, y0) * (1.0 - fx) + m(x1, y0) * fx;
        let bottom = m(x0, y1) * (1.0 - fx) + m(x1, y1) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    }

    /// Rim points on `rays` rays from `centre` out to `reach` px: on each, the outer point
    /// where the magnitude falls to [`RIM_FRACTION`] of the way from the baseline to the
    /// ray's reference height, when the ray's peak is above `threshold` and the fall lies
    /// inside the image. The reference is the geometric mean of the ray's own peak and the
    /// contact's `peak` (both above the baseline): the ray's own, because the LEDs show
    /// slopes facing some ways more strongly than others; the contact's, because on a real
    /// sensor the weakly shown directions are also the broad ones (the gel's deformation
    /// outside the contact), and a ray read only against its own peak runs far out along
    /// them.
    pub fn rim_points(
        &self,
        (cx, cy): (f64, f64),
        reach: f64,
        rays: usize,
        threshold: f64,
        peak: f64,
    ) -> Vec<(f64, f64)> {
        let steps = (reach / RAY_STEP_PX).ceil() as usize;
        let mut out = Vec::with_capacity(rays);
        let mut profile = Vec::with_capacity(steps + 1);
        for k in 0..rays {
            let (s, c) = (std::f64::consts::TAU * k as f64 / rays as f64).sin_cos();
            profile.clear();
            for i in 0..=steps {
                let rho = i as f64 * RAY_STEP_PX;
                match self.at(cx + rho * c, cy + rho * s) {
                    Some(v) => profile.push(v),
                    None => break,
                }
            }
            let Some(rho) = self.rim_fall(&profile, threshold, peak) else {
                continue;
            };
            out.push((cx + rho * c, cy + rho * s));
        }
        out
    }

    /// Where `profile` (sampled every [`RAY_STEP_PX`]) falls below the rim level (see
    /// [`Self::rim_points`]), after its peak, px from its start.
    fn rim_fall(&self, profile: &[f64], threshold: f64, contact_peak: f64) -> Option<f64> {
        let (peak_i, peak) =
            profile
                .iter()
                .copied()
                .enumerate()
                .fold(
                    (0, f64::MIN),
                    |best, (i, v)| if v > best.1 { (i, v) } else { best },
                );
        if peak <= threshold {
            return None;
        }
        let reference = ((peak - self.baseline) * (contact_peak - self.baseline).max(0.0)).sqrt();
        // A ray under a quarter of the contact's peak does not reach its own rim level.
        let level = self.baseline + RIM_FRACTION * reference;
        if peak <= level {
            return None;
        }
        let i = (peak_i..profile.len()).find(|&i| profile[i] < level)?;
        let (a, b) = (profile[i - 1], profile[i]);
        let t = if a > b { (a - level) / (a - b) } else { 0.0 };
        Some((i as f64 - 1.0 + t) * RAY_STEP_PX)
    }
}

/// The median of `v` (0 for none; non-finite values sort last).
fn median(mut v: Vec<f32>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    f64::from(*m)
}

/// Box blur of one channel in place, `(2r + 1)²`, edges replicated.
fn box_blur(v: &mut [f32], w: usize, h: usize, r: usize) {
    if r == 0 || w == 0 || h == 0 {
        return;
    }
    let n = (2 * r + 1) as f32;
    let mut line = Vec::new();
    let pass = |v: &mut [f32],
                len: usize,
                count: usize,
                idx: &dyn Fn(usize, usize) -> usize,
                line: &mut Vec<f32>| {
        for j in 0..count {
            line.clear();
            line.extend((0..len).map(|i| v[idx(j, i)]));
            let at = |i: isize| line[i.clamp(0, len as isize - 1) as usize];
            let ri = r as isize;
            let mut sum: f32 = (-ri..=ri).map(at).sum();
            for i in 0..len {
                v[idx(j, i)] = sum / n;
                sum += at(i as isize + ri + 1) - at(i as isize - ri);
            }
        }
    };
    pass(v, w, h, &|row, i| row * w + i, &mut line);
    pass(v, h, w, &|col, i| i * w + col, &mut line);
}
