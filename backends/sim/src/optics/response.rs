//! What a per-pixel gradient model can read from a sensor's colours: its **response curve**.
//!
//! A look-up table is trained on labelled pixels (each pixel's colour difference from the
//! background, binned [`COLOUR_BIN`] grey levels wide per channel, holds the mean gradient
//! of its samples, as the classic table of `calibrate train --model lut --loss l2` does), and
//! read back on the same pixels;
//! the reading's component along each pixel's true slope direction is averaged per
//! true-slope bin ([`SLOPE_BINS`] of [`SLOPE_BIN`]). An optics whose colour keeps changing
//! with the slope reads back the slope; one whose channels clip, or whose colour turns back
//! at steep slopes, reads a curve that flattens there.
//!
//! [`crate::optics::fit`] matches the simulator's curve to the real Mini's (its labelled
//! presses, the ball's cap for the truth) beside the colours' sector means: the sector means
//! alone leave the LEDs' elevation almost free (docs/calibration.md).

use std::collections::HashMap;

use rand_distr::{Distribution, Normal};

use super::fit::{Contact, Image, PressGeometry};
use super::realistic::{RealisticParams, RealisticShader};
use crate::unit::{UnitVariation, rng_for};

/// True-slope bins of a [`ResponseCurve`].
pub const SLOPE_BINS: usize = 10;
/// Width of a true-slope bin (the curve covers slopes 0 to 1).
pub const SLOPE_BIN: f64 = 0.1;
/// Width of the table's colour bins, grey levels per channel.
pub const COLOUR_BIN: f64 = 4.0;

/// One labelled pixel: its colour difference from the background and its true gradient.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LabelledPixel {
    /// Press − background per channel, grey levels.
    pub colour_diff: [f64; 3],
    /// True surface gradient (x, y).
    pub gradient: [f64; 2],
}

/// Per true-slope bin: the mean reading along the true slope direction, and the pixels it
/// averages.
#[derive(Debug, Clone, PartialEq)]
pub struct ResponseCurve {
    /// Mean reading per bin (0 for an empty bin).
    pub read: [f64; SLOPE_BINS],
    /// Pixels per bin.
    pub count: [usize; SLOPE_BINS],
}

impl ResponseCurve {
    /// The curve of a table trained and read on `pixels` (non-finite values skipped).
    pub fn of(pixels: &[LabelledPixel]) -> Self {
        let key = |p: &LabelledPixel| p.colour_diff.map(|c| (c / COLOUR_BIN).floor() as i32);
        let mut table: HashMap<[i32; 3], ([f64; 2], usize)> = HashMap::new();
        let finite = |p: &&LabelledPixel| {
            p.colour_diff
                .iter()
                .chain(&p.gradient)
                .all(|v| v.is_finite())
        };
        for p in pixels.iter().filter(finite) {
            let bin = table.entry(key(p)).or_insert(([0.0; 2], 0));
            bin.0[0] += p.gradient[0];
            bin.0[1] += p.gradient[1];
            bin.1 += 1;
        }
        let (mut sums, mut count) = ([0.0; SLOPE_BINS], [0usize; SLOPE_BINS]);
        for p in pixels.iter().filter(finite) {
            let slope = p.gradient[0].hypot(p.gradient[1]);
            let bin = (slope / SLOPE_BIN).floor();
            if slope <= 0.0 || bin >= SLOPE_BINS as f64 {
                continue;
            }
            let Some((sum, n)) = table.get(&key(p)) else {
                continue;
            };
            let read = [sum[0] / *n as f64, sum[1] / *n as f64];
            let along = (read[0] * p.gradient[0] + read[1] * p.gradient[1]) / slope;
            sums[bin as usize] += along;
            count[bin as usize] += 1;
        }
        let mut read = [0.0; SLOPE_BINS];
        for ((r, s), n) in read.iter_mut().zip(sums).zip(count) {
            *r = if n > 0 { s / n as f64 } else { 0.0 };
        }
        Self { read, count }
    }

    /// RMS difference of the readings from `other`'s over the bins both have pixels in
    /// (slope units; 0 when none).
    pub fn rms_from(&self, other: &Self) -> f64 {
        let (mut se, mut n) = (0.0, 0usize);
        for i in 0..SLOPE_BINS {
            if self.count[i] > 0 && other.count[i] > 0 {
                se += (self.read[i] - other.read[i]).powi(2);
                n += 1;
            }
        }
        if n == 0 { 0.0 } else { (se / n as f64).sqrt() }
    }
}

/// Every `stride`-th pixel (rows and columns) inside each contact the ball touches, as
/// `geometry` presses it: (x, y, true gradient). The gradient is the ball's cap's.
fn contact_pixels(
    contact: &Contact,
    geometry: &PressGeometry,
    (w, h): (usize, usize),
    stride: usize,
) -> Vec<(usize, usize, [f64; 2])> {
    let press = geometry.press(contact.radius_px);
    let a = geometry.contact_share * contact.radius_px;
    let (cx, cy) = (contact.center_x_px, contact.center_y_px);
    let span = |c: f64, n: usize| {
        let lo = (c - a).floor().max(0.0) as usize;
        lo..((c + a).ceil().max(0.0) as usize).min(n)
    };
    let mut out = Vec::new();
    for y in span(cy, h).step_by(stride.max(1)) {
        for x in span(cx, w).step_by(stride.max(1)) {
            let (dx, dy) = (x as f64 - cx, y as f64 - cy);
            let rho = dx.hypot(dy);
            if rho >= a || rho <= 0.0 {
                continue;
            }
            let (_, slope) = press.at(rho);
            out.push((x, y, [slope * dx / rho, slope * dy / rho]));
        }
    }
    out
}

/// The labelled pixels of real `presses` against `background`, each contact pressed by
/// the ball as `geometry` says.
pub fn real_pixels(
    background: Image<'_>,
    presses: &[(Contact, Image<'_>)],
    geometry: &PressGeometry,
    stride: usize,
) -> Vec<LabelledPixel> {
    let size = (background.width_px, background.height_px);
    let mut out = Vec::new();
    for (contact, img) in presses {
        for (x, y, gradient) in contact_pixels(contact, geometry, size, stride) {
            let colour_diff = [0, 1, 2].map(|c| img.at(x, y, c) - background.at(x, y, c));
            out.push(LabelledPixel {
                colour_diff,
                gradient,
            });
        }
    }
    out
}

/// The same pixels rendered with `params` (the camera's noise on the press and on the
/// background, drawn from a fixed seed, so a fit sees a smooth loss).
pub fn model_pixels(
    params: &RealisticParams,
    size: (usize, usize),
    contacts: &[Contact],
    geometry: &PressGeometry,
    stride: usize,
) -> Vec<LabelledPixel> {
    let shader = RealisticShader::new(params, size.0, size.1, &UnitVariation::NEUTRAL);
    let noise = params
        .noise_rgb
        .map(|s| Normal::new(0.0, s.max(0.0) * std::f64::consts::SQRT_2).ok());
    let mut rng = rng_for(11, 0);
    let mut out = Vec::new();
    for contact in contacts {
        for (x, y, gradient) in contact_pixels(contact, geometry, size, stride) {
            let lit = shader.shade(x, y, gradient[0], gradient[1]);
            let flat = shader.shade(x, y, 0.0, 0.0);
            let colour_diff = [0, 1, 2].map(|c| {
                let n = noise[c].map_or(0.0, |d| d.sample(&mut rng));
                lit[c].clamp(0.0, 255.0) - flat[c].clamp(0.0, 255.0) + n
            });
            out.push(LabelledPixel {
                colour_diff,
                gradient,
            });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pixel(colour_diff: [f64; 3], gradient: [f64; 2]) -> LabelledPixel {
        LabelledPixel {
            colour_diff,
            gradient,
        }
    }

    #[test]
    fn colour_that_follows_the_slope_reads_it_back() {
        // Red grows with gx: every slope has its own colour bin.
        let pixels: Vec<_> = (1..100)
            .map(|i| {
                let g = f64::from(i) * 0.01;
                pixel([g * 200.0, 0.0, 0.0], [g, 0.0])
            })
            .collect();
        let curve = ResponseCurve::of(&pixels);
        for (i, r) in curve.read.iter().enumerate() {
            let mid = (i as f64 + 0.5) * SLOPE_BIN;
            assert!((r - mid).abs() < 0.03, "bin {i}: {r}");
        }
    }

    #[test]
    fn clipped_colour_reads_the_mean_of_what_it_hides() {
        // Red clips at a slope of 0.3: everything steeper shares one colour bin.
        let pixels: Vec<_> = (1..100)
            .map(|i| {
                let g = f64::from(i) * 0.01;
                pixel([g.min(0.3) * 200.0, 0.0, 0.0], [g, 0.0])
            })
            .collect();
        let curve = ResponseCurve::of(&pixels);
        assert!(curve.read[9] < 0.7, "{:?}", curve.read);
        assert!(curve.read[1] > 0.1 && curve.read[1] < 0.2);
        let truth = ResponseCurve::of(
            &(1..100)
                .map(|i| pixel([f64::from(i) * 2.0, 0.0, 0.0], [f64::from(i) * 0.01, 0.0]))
                .collect::<Vec<_>>(),
        );
        assert!(curve.rms_from(&truth) > 0.1);
        assert_eq!(truth.rms_from(&truth), 0.0);
    }

    #[test]
    fn non_finite_pixels_are_skipped() {
        let pixels = [
            pixel([f64::NAN, 0.0, 0.0], [0.5, 0.0]),
            pixel([10.0, 0.0, 0.0], [f64::INFINITY, 0.0]),
            pixel([10.0, 0.0, 0.0], [0.25, 0.0]),
        ];
        let curve = ResponseCurve::of(&pixels);
        assert_eq!(curve.count.iter().sum::<usize>(), 1);
        assert!(curve.read.iter().all(|r| r.is_finite()));
    }
}
