//! The difference field a contact is found in: the magnitude of (press − background), each
//! channel divided by the background's local level (the LEDs' falloff flattened), less its
//! median and box-blurred, with its noise level, its blobs above the noise and its rim along
//! rays.

use crate::image::RgbImage;

use super::edge;
use super::{BACKGROUND_SMOOTH_PX, MIN_BLOB_PX, NOISE_SIGMAS, RIM_FRACTION, SIGNAL_SIGMAS};

/// Step along a ray, px.
const RAY_STEP_PX: f64 = 0.5;
/// Rays run this far past the ball's radius (in its units) to see a rim's fall.
const RAY_REACH: f64 = 1.5;

/// |press − background| per pixel, with the noise statistics of the frame.
#[derive(Debug, Clone)]
pub struct DiffField {
    width: usize,
    height: usize,
    /// The blurred difference's magnitude as the camera gives it (its noise is the same
    /// everywhere): where the contact is, and how far above the noise.
    signal: Vec<f32>,
    /// The same with each channel divided by the LEDs' light there: where its rim is.
    magnitude: Vec<f32>,
    /// The blurred difference divided by the light, channel by channel.
    channels: Vec<Vec<f32>>,
    /// The blurred difference as the camera gives it, channel by channel: where a step is
    /// (the light is smooth across it, and dividing by it would scale up the noise and the
    /// JPEG's ringing where the pad is dark).
    camera: Vec<Vec<f32>>,
    /// `signal`'s median.
    baseline: f64,
    /// `magnitude`'s median.
    lit_baseline: f64,
    spread: f64,
    /// The camera's noise in the difference, per channel, grey levels (before the blur).
    camera_noise: f64,
    blur_px: usize,
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
        let mut raw: Vec<Vec<f32>> = (0..3)
            .map(|c| {
                (0..n)
                    .map(|p| {
                        f32::from(press.data[3 * p + c]) - f32::from(background.data[3 * p + c])
                    })
                    .collect()
            })
            .collect();
        let mut noise = Vec::with_capacity(3);
        for ch in &mut raw {
            let shift = median(ch.iter().step_by(7).copied().collect()) as f32;
            ch.iter_mut().for_each(|v| *v -= shift);
            noise.push(high_pass_sigma(ch, w, h));
        }
        // The three channels' noise as one figure (their RMS), never under the 8-bit
        // quantisation's own (1/√12 of a grey level).
        let camera_noise = (noise.iter().map(|s| s * s).sum::<f64>() / 3.0)
            .sqrt()
            .max(QUANTISATION_SIGMA);
        let mut channels: Vec<Vec<f32>> = raw
            .iter()
            .enumerate()
            .map(|(c, ch)| {
                let gain = lighting_gain(background, c);
                ch.iter().zip(&gain).map(|(d, g)| d * g).collect()
            })
            .collect();
        for ch in raw.iter_mut().chain(channels.iter_mut()) {
            box_blur(ch, w, h, blur_px);
        }
        let magnitude_of = |planes: &[Vec<f32>]| -> Vec<f32> {
            (0..n)
                .map(|p| (planes.iter().map(|c| c[p] * c[p]).sum::<f32>()).sqrt())
                .collect()
        };
        let signal = magnitude_of(&raw);
        let magnitude = magnitude_of(&channels);
        let camera = raw;
        let (baseline, spread) = level_and_spread(&signal);
        let (lit_baseline, _) = level_and_spread(&magnitude);
        Self {
            width: w,
            height: h,
            signal,
            magnitude,
            channels,
            camera,
            baseline,
            lit_baseline,
            spread,
            camera_noise,
            blur_px,
        }
    }

    /// The camera's noise in the difference image, per channel, grey levels: the spread of
    /// what a 3×3 mean does not explain (the pixel-to-pixel noise, which the press's smooth
    /// shading does not reach), at least the 8-bit quantisation's.
    pub fn camera_noise(&self) -> f64 {
        self.camera_noise
    }

    /// The noise `camera_noise` (per channel, unblurred) leaves in the blurred magnitude:
    /// the unit the signal threshold and the shallowness are measured in.
    pub fn magnitude_noise(&self, camera_noise: f64) -> f64 {
        let side = (2 * self.blur_px + 1) as f64;
        camera_noise * 3f64.sqrt() / side
    }

    /// The magnitude of untouched gel (the frame's median), grey levels.
    pub fn baseline(&self) -> f64 {
        self.baseline
    }

    /// The magnitude above which a pixel is signal, given the dataset's camera noise:
    /// [`SIGNAL_SIGMAS`] of the frame's own spread (MAD) above its baseline, and at least
    /// [`NOISE_SIGMAS`] of the noise the camera leaves in the magnitude.
    pub fn threshold(&self, camera_noise: f64) -> f64 {
        self.baseline
            + (SIGNAL_SIGMAS * self.spread).max(NOISE_SIGMAS * self.magnitude_noise(camera_noise))
    }

    /// Blobs above `threshold` of at least [`MIN_BLOB_PX`] pixels, largest first.
    pub fn blobs(&self, threshold: f64) -> Vec<Blob> {
        let (w, h) = (self.width, self.height);
        let above: Vec<bool> = self
            .signal
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
            let m = f64::from(self.signal[p]);
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

    /// `a` and `b` as one blob (the parts of one contact).
    pub fn merge(&self, a: Blob, b: Blob, threshold: f64) -> Blob {
        let mut pixels = a.pixels;
        pixels.extend(b.pixels);
        self.blob(pixels, threshold)
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
        self.sample(&self.magnitude, x, y)
    }

    /// The three channels of `planes` at (`x`, `y`); `None` outside the image.
    fn colour_at(&self, planes: &[Vec<f32>], x: f64, y: f64) -> Option<[f64; 3]> {
        Some([
            self.sample(&planes[0], x, y)?,
            self.sample(&planes[1], x, y)?,
            self.sample(&planes[2], x, y)?,
        ])
    }

    /// Bilinear value of `plane` at (`x`, `y`); `None` outside the image.
    fn sample(&self, plane: &[f32], x: f64, y: f64) -> Option<f64> {
        let (w, h) = (self.width, self.height);
        if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f64 && y <= (h - 1) as f64) {
            return None;
        }
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f64, y - y0 as f64);
        let m = |x: usize, y: usize| f64::from(plane[y * w + x]);
        let top = m(x0, y0) * (1.0 - fx) + m(x1, y0) * fx;
        let bottom = m(x0, y1) * (1.0 - fx) + m(x1, y1) * fx;
        Some(top * (1.0 - fy) + bottom * fy)
    }

    /// Rim points on `rays` rays from `centre`, out to [`RAY_REACH`] times the ball's radius
    /// `ball_px` (a rim beyond the ball is found, and its circle refused, rather than cut
    /// down to size). On each ray whose signal rises above `threshold`, the rim is read two
    /// ways (see [`Self::read_rim`]); where the contact's rim is a step (on the median ray
    /// the fitted jump is at least [`STEP_SHARE`] of the ray's peak), the step fitted on
    /// each ray is its rim, else the reading from the magnitude's fall and the colour's
    /// change.
    pub fn rim_points(
        &self,
        (cx, cy): (f64, f64),
        ball_px: f64,
        rays: usize,
        threshold: f64,
        noise_unit: f64,
    ) -> RimPoints {
        let steps = (ball_px * RAY_REACH / RAY_STEP_PX).ceil() as usize;
        let blur = edge::BoxBlur::new(self.blur_px);
        let readings: Vec<((f64, f64), RimReading)> = (0..rays)
            .filter_map(|k| {
                let (s, c) = (std::f64::consts::TAU * k as f64 / rays as f64).sin_cos();
                let ray = self.cast((cx, cy), (c, s), steps, threshold)?;
                let reading = self.read_rim(&ray, (c, s), &blur, ball_px, noise_unit)?;
                Some(((c, s), reading))
            })
            .collect();
        let mut shares: Vec<f32> = readings
            .iter()
            .map(|(_, r)| r.step.map_or(0.0, |st| (st.jump / r.peak) as f32))
            .collect();
        let stepped = !shares.is_empty() && median(std::mem::take(&mut shares)) >= STEP_SHARE;
        let points = readings
            .into_iter()
            .map(|((c, s), r)| {
                let rho = match r.step {
                    Some(st) if stepped => st.rho,
                    _ => r.from_fall,
                };
                (cx + rho * c, cy + rho * s)
            })
            .collect();
        RimPoints { points, stepped }
    }

    /// The contact's rim read where the colour's path turns: on `rays` rays from `centre`
    /// out to the ball's radius `ball_px`, each whose signal rises above `threshold`, the
    /// sharpest turn of the lit colour's path ([`colour_turn`]). Where the gel's surface
    /// follows the ball inside the contact and sinks back to level outside it (a gel with
    /// a skirt, whose visible imprint is wider than the contact), its slope is steepest at
    /// the contact's rim: the colour moves one way with the slope on the way there and
    /// turns back after it. An LED response that brightens with the slope and darkens
    /// again past some slope turns the path too, at one distance from the centre whatever
    /// the press; which of the two a dataset's turns are, the dataset says
    /// (`Labeller::with_dataset_rims`).
    pub fn turn_points(
        &self,
        (cx, cy): (f64, f64),
        ball_px: f64,
        rays: usize,
        threshold: f64,
        noise_unit: f64,
    ) -> RimPoints {
        let steps = (ball_px / RAY_STEP_PX).floor() as usize;
        let reach = ((TURN_REACH * ball_px / RAY_STEP_PX).round() as usize).max(1);
        let points = (0..rays)
            .filter_map(|k| {
                let (s, c) = (std::f64::consts::TAU * k as f64 / rays as f64).sin_cos();
                let ray = self.cast((cx, cy), (c, s), steps, threshold)?;
                let rho = colour_turn(&ray.colours, reach, STEP_SNR * noise_unit)?;
                Some((cx + rho * c, cy + rho * s))
            })
            .collect();
        RimPoints {
            points,
            stepped: false,
        }
    }

    /// The ray from `centre` in direction `dir`, every [`RAY_STEP_PX`] for `steps` steps
    /// or to the image's edge; `None` when the signal never rises above `threshold` on it.
    fn cast(
        &self,
        (cx, cy): (f64, f64),
        (c, s): (f64, f64),
        steps: usize,
        threshold: f64,
    ) -> Option<Ray> {
        let mut ray = Ray {
            profile: Vec::new(),
            colours: Vec::new(),
            camera: Vec::new(),
            signal_peak: f64::MIN,
        };
        for i in 0..=steps {
            let (x, y) = (
                cx + i as f64 * RAY_STEP_PX * c,
                cy + i as f64 * RAY_STEP_PX * s,
            );
            let (Some(v), Some(col), Some(cam), Some(sig)) = (
                self.at(x, y),
                self.colour_at(&self.channels, x, y),
                self.colour_at(&self.camera, x, y),
                self.sample(&self.signal, x, y),
            ) else {
                break;
            };
            ray.profile.push(v);
            ray.colours.push(col);
            ray.camera.push(cam);
            ray.signal_peak = ray.signal_peak.max(sig);
        }
        (ray.signal_peak > threshold).then_some(ray)
    }

    /// A ray's rim read from its lit `profile` and `colours`: the outer point where the
    /// magnitude falls [`RIM_FRACTION`] of the way from the untouched gel to the ray's own
    /// peak (a step in slope blurred by the optics is at half height at the step, whatever
    /// the LEDs' gain for the slope's direction), moved to the centre of the colour's
    /// largest change within [`STEP_WINDOW`] of the ball's radius where that change stands
    /// [`STEP_SNR`] times above the noise (`noise_unit`); and, in the same window, the
    /// step fitted to the channels ([`edge::fit_step`]) where its jump stands
    /// [`STEP_SNR`] times above the noise. `None` when the magnitude never falls.
    fn read_rim(
        &self,
        ray: &Ray,
        direction: (f64, f64),
        blur: &edge::BoxBlur,
        ball_px: f64,
        noise_unit: f64,
    ) -> Option<RimReading> {
        let fall = self.rim_fall(&ray.profile)?;
        let window = STEP_WINDOW * ball_px;
        let centre = (fall / RAY_STEP_PX).round() as usize;
        let half = (window / RAY_STEP_PX).ceil() as usize;
        let to = (centre + half).min(ray.colours.len().saturating_sub(1));
        let from_fall = match colour_step(&ray.colours, centre.saturating_sub(half), to) {
            Some((rho, change)) if change >= STEP_SNR * noise_unit => rho,
            _ => fall,
        };
        let samples = edge::RaySamples {
            colours: &ray.camera,
            step_px: RAY_STEP_PX,
            direction,
            blur,
        };
        let step = edge::fit_step(samples, (fall - window, fall + window), blur.width_px())
            .filter(|st| st.jump >= STEP_SNR * noise_unit);
        let peak = ray.signal_peak - self.baseline;
        Some(RimReading {
            from_fall,
            step,
            peak,
        })
    }

    /// Where the lit `profile` (sampled every [`RAY_STEP_PX`]) falls to the rim level after
    /// its peak, px from its start (see [`Self::rim_points`]).
    fn rim_fall(&self, profile: &[f64]) -> Option<f64> {
        let (peak_i, peak) =
            profile
                .iter()
                .copied()
                .enumerate()
                .fold(
                    (0, f64::MIN),
                    |best, (i, v)| if v > best.1 { (i, v) } else { best },
                );
        let base = self.lit_baseline;
        if peak <= base {
            return None;
        }
        let level = base + RIM_FRACTION * (peak - base);
        let i = (peak_i..profile.len()).find(|&i| profile[i] < level)?;
        let (a, b) = (profile[i - 1], profile[i]);
        let t = if a > b { (a - level) / (a - b) } else { 0.0 };
        Some((i as f64 - 1.0 + t) * RAY_STEP_PX)
    }
}

/// A ray's colour step (or fitted jump) counts when it is this many times the camera's
/// noise in the blurred magnitude; a fainter one is read from the magnitude's fall instead.
const STEP_SNR: f64 = 8.0;
/// A contact's rim is a step when, on its median ray, the fitted jump is at least this
/// share of the ray's peak: on the simulator's presses the median share is 0.48 or more
/// (its gel's slope jumps from the ball's to flat at the rim), on the GelSight Mini's at
/// most 0.09 (the real gel's slope runs on past the contact; the ray with the largest
/// share there has 0.29). A quarter lies between, with room either side.
const STEP_SHARE: f64 = 0.25;

/// A contact's rim points, one per ray that found it, and whether the rim is a step (the
/// fitted steps are the points) or not.
#[derive(Debug, Clone)]
pub struct RimPoints {
    /// The points, px.
    pub points: Vec<(f64, f64)>,
    /// Whether the contact's rim is a step.
    pub stepped: bool,
}

/// One ray's samples.
#[derive(Debug, Clone)]
struct Ray {
    /// The lit magnitude.
    profile: Vec<f64>,
    /// The lit channels.
    colours: Vec<[f64; 3]>,
    /// The camera's channels.
    camera: Vec<[f64; 3]>,
    /// The largest signal (the camera's magnitude) on the ray.
    signal_peak: f64,
}

/// A ray's rim, read both ways (see [`DiffField::read_rim`]).
#[derive(Debug, Clone, Copy)]
struct RimReading {
    /// From the magnitude's fall and the colour's largest change, px from the centre.
    from_fall: f64,
    /// The step fitted to the channels, where its jump stands above the noise.
    step: Option<edge::Step>,
    /// The ray's peak signal over the untouched gel's.
    peak: f64,
}
/// How far either side of the magnitude's fall a ray looks for the colour's step, in units
/// of the ball's radius.
const STEP_WINDOW: f64 = 0.15;
/// Samples either side of a point that the colour's change across it is measured over.
const STEP_HALF_SAMPLES: usize = 2;

/// Where along a ray the colour of the difference changes most between samples `from` and
/// `to` (the rim: the gel's slope steps from the ball's to flat there, and the optics blur
/// that step into a box-shaped change): the centroid of the change where it is above half
/// its largest, px from the ray's start, and that largest change.
fn colour_step(colours: &[[f64; 3]], from: usize, to: usize) -> Option<(f64, f64)> {
    let k = STEP_HALF_SAMPLES;
    let (from, to) = (from.max(k), to.min(colours.len().saturating_sub(k + 1)));
    if from >= to {
        return None;
    }
    let change: Vec<f64> = (from..=to)
        .map(|i| {
            let (a, b) = (colours[i - k], colours[i + k]);
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
        })
        .collect();
    let (at, top) = peak_centroid(&change)?;
    Some(((at + from as f64) * RAY_STEP_PX, top))
}

/// The largest of `values` (above 0) and the centroid of the run of values around it that
/// stay above half of it, in `values`' indices; `None` when none is above 0.
fn peak_centroid(values: &[f64]) -> Option<(f64, f64)> {
    let (top_j, top) = values
        .iter()
        .copied()
        .enumerate()
        .fold(
            (0, f64::MIN),
            |best, (j, v)| if v > best.1 { (j, v) } else { best },
        );
    if top.is_nan() || top <= 0.0 {
        return None;
    }
    let half = 0.5 * top;
    let first = (0..=top_j)
        .rev()
        .take_while(|&j| values[j] >= half)
        .last()?;
    let last = (top_j..values.len())
        .take_while(|&j| values[j] >= half)
        .last()?;
    let (sum, weighted) = (first..=last).fold((0.0, 0.0), |(s, w), j| {
        (s + values[j], w + values[j] * j as f64)
    });
    Some((weighted / sum, top))
}

/// How far either side of a point a colour path's turn is measured, in units of the
/// ball's radius.
const TURN_REACH: f64 = 0.1;

/// Where the colour path `colours` (sampled every [`RAY_STEP_PX`]) turns most sharply: at
/// each sample, the colour's moves over `reach` samples before it (u) and after it (v),
/// scored |u||v| − u·v (0 on a straight path, 2|u||v| where it runs back the way it came,
/// so a turn counts as much as the moves either side of it are large); the centroid of
/// the score where it is above half its largest, px from the path's start. `None` when
/// no turn's moves reach `least_move` (grey levels) each, or its score `least_move`²
/// (a straight path's is nothing but rounding).
pub(super) fn colour_turn(colours: &[[f64; 3]], reach: usize, least_move: f64) -> Option<f64> {
    if colours.len() <= 2 * reach {
        return None;
    }
    let moved = |a: [f64; 3], b: [f64; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let norm = |u: [f64; 3]| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
    let scores: Vec<f64> = (reach..colours.len() - reach)
        .map(|i| {
            let u = moved(colours[i - reach], colours[i]);
            let v = moved(colours[i], colours[i + reach]);
            let (nu, nv) = (norm(u), norm(v));
            if nu < least_move || nv < least_move {
                return 0.0;
            }
            nu * nv - (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])
        })
        .collect();
    let (at, top) = peak_centroid(&scores)?;
    // Not a turn when under the least score, or when the least move is not a number.
    if top
        .partial_cmp(&(least_move * least_move))
        .is_none_or(std::cmp::Ordering::is_lt)
    {
        return None;
    }
    Some((at + reach as f64) * RAY_STEP_PX)
}

/// Per pixel, what the difference of channel `c` is multiplied by to read as at a pixel of
/// the channel's median light: the median over the background's level there (box-blurred
/// over [`BACKGROUND_SMOOTH_PX`], at least 1).
fn lighting_gain(background: &RgbImage, c: usize) -> Vec<f32> {
    let (w, h) = (background.width, background.height);
    let mut level: Vec<f32> = (0..w * h)
        .map(|p| f32::from(background.data[3 * p + c]))
        .collect();
    let reference = median(level.iter().step_by(7).copied().collect()).max(1.0) as f32;
    box_blur(&mut level, w, h, BACKGROUND_SMOOTH_PX);
    level.iter().map(|l| reference / l.max(1.0)).collect()
}

/// The median of `v` and its spread (1.4826 × MAD), from every third value.
fn level_and_spread(v: &[f32]) -> (f64, f64) {
    let sample: Vec<f32> = v.iter().step_by(3).copied().collect();
    let level = median(sample.clone());
    let spread = 1.4826
        * median(
            sample
                .iter()
                .map(|x| (f64::from(*x) - level).abs() as f32)
                .collect(),
        );
    (level, spread)
}

/// The 8-bit quantisation's noise, grey levels.
const QUANTISATION_SIGMA: f64 = 0.288_675_134_594_812_9;

/// The noise of one channel `v` (`w`×`h`): 1.4826 × the median absolute residual from the
/// 3×3 mean, scaled by √(9/8) for the pixel's own share of that mean.
fn high_pass_sigma(v: &[f32], w: usize, h: usize) -> f64 {
    if w < 3 || h < 3 {
        return 0.0;
    }
    let mut smooth = v.to_vec();
    box_blur(&mut smooth, w, h, 1);
    let residual: Vec<f32> = (1..h - 1)
        .flat_map(|y| (1..w - 1).map(move |x| y * w + x))
        .step_by(3)
        .map(|p| (v[p] - smooth[p]).abs())
        .collect();
    1.4826 * median(residual) * (9.0f64 / 8.0).sqrt()
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
