//! The rim along one ray as a step: where the gel's slope jumps from the ball's to flat,
//! every colour channel of the difference jumps with it, whatever the LEDs make of the
//! slopes on either side. For each place ρ the rim might be, the ray's blurred channels
//! are fitted with a line on either side of a jump at the circle of radius ρ, blurred as
//! the detector blurred the image; the jump is largest where the model's step lies on
//! the data's, and the rim is the centroid of the jump's curve above half its largest.
//!
//! The ray's peak and its half-height place a rim only where the difference is largest at
//! the rim. At steep slopes (a deep press) the LEDs' response turns over: inside the rim
//! some channels cross zero, the magnitude falls to half its peak pixels before the rim,
//! and the colour changes fastest there, while the step itself stands in the other
//! channels. The lines take up the smooth change on either side, so the jump is the
//! step's alone; the model is blurred with the detector's own box across a circular rim
//! (a box blur moves a small circle's edge inwards). Where the channels are level on
//! either side the jump's curve is symmetric about the step for any further symmetric
//! blur of the camera; a slope inside moves it by a fraction of a pixel (0.2 px where the
//! channels change by an eighth of the jump per pixel; the tests).

/// A step fitted along a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Where the jump is, px from the ray's start (the circle's radius).
    pub rho: f64,
    /// The jump's size across the three channels (the length of its colour vector), grey
    /// levels, at its largest.
    pub jump: f64,
}

/// Candidate places per sample of the ray.
const CANDIDATES_PER_SAMPLE: f64 = 4.0;
/// Points of the blur's box per pixel, each way.
const KERNEL_SAMPLES: f64 = 4.0;

/// The blur a detector applied to the image: a box of radius `blur_px` over the pixel
/// grid, and each pixel's own area, as offsets from a sample.
#[derive(Debug, Clone)]
pub struct BoxBlur {
    offsets: Vec<(f64, f64)>,
}

impl BoxBlur {
    /// The box of radius `blur_px`.
    pub fn new(blur_px: usize) -> Self {
        let side = (2 * blur_px + 1) as f64;
        let n = (side * KERNEL_SAMPLES) as usize;
        let at = |i: usize| -0.5 * side + side * (i as f64 + 0.5) / n as f64;
        Self {
            offsets: (0..n)
                .flat_map(|i| (0..n).map(move |j| (at(i), at(j))))
                .collect(),
        }
    }

    /// The box's width, px.
    pub fn width_px(&self) -> f64 {
        2.0 * self.offsets.iter().fold(0.0f64, |m, o| m.max(o.0.abs())) + 1.0 / KERNEL_SAMPLES
    }
}

/// A ray to fit: its blurred channels, one sample every `step_px` from the centre of the
/// circle along (`cos`, `sin`), blurred by `blur`.
#[derive(Debug, Clone, Copy)]
pub struct RaySamples<'a> {
    /// The channels.
    pub colours: &'a [[f64; 3]],
    /// Between samples, px.
    pub step_px: f64,
    /// The ray's direction.
    pub direction: (f64, f64),
    /// The blur.
    pub blur: &'a BoxBlur,
}

/// The step on `ray` placed between `from_px` and `to_px` from its start; the model is
/// fitted over `half_window_px` either side of each place. `None` when no window fits on
/// the ray.
pub fn fit_step(
    ray: RaySamples<'_>,
    (from_px, to_px): (f64, f64),
    half_window_px: f64,
) -> Option<Step> {
    let step = ray.step_px;
    if !(from_px.is_finite() && to_px.is_finite() && step > 0.0) || to_px <= from_px {
        return None;
    }
    let half = (half_window_px / step).ceil() as isize;
    let last = ray.colours.len() as isize - 1;
    let first_sample = ((from_px / step).round() as isize - half).max(0);
    let last_sample = ((to_px / step).round() as isize + half).min(last);
    if first_sample > last_sample {
        return None;
    }
    let radii: Vec<SampleRadii> = (first_sample..=last_sample)
        .map(|i| SampleRadii::new(i as f64 * step, ray.direction, ray.blur))
        .collect();
    let spacing = step / CANDIDATES_PER_SAMPLE;
    let count = ((to_px - from_px) / spacing).ceil() as usize;
    let curve: Vec<(f64, f64)> = (0..=count)
        .map(|k| {
            let rho = from_px + k as f64 * spacing;
            let centre = (rho / step).round() as isize;
            let (lo, hi) = (centre - half, centre + half);
            let jump = if lo < first_sample || hi > last_sample {
                None
            } else {
                let rows = (lo..=hi).map(|i| {
                    let at = (i - first_sample) as usize;
                    (radii[at].basis(rho), ray.colours[i as usize])
                });
                jump_at(rows)
            };
            (rho, jump.unwrap_or(f64::NAN))
        })
        .collect();
    let (top, jump) = curve
        .iter()
        .enumerate()
        .filter(|(_, c)| c.1.is_finite())
        .max_by(|a, b| a.1.1.total_cmp(&b.1.1))
        .map(|(i, c)| (i, c.1))?;
    let level = 0.5 * jump;
    let above = |k: &usize| curve[*k].1 >= level;
    let first = (0..=top).rev().take_while(above).last().unwrap_or(top);
    let last = (top..curve.len()).take_while(above).last().unwrap_or(top);
    let (weight, moment) = curve[first..=last]
        .iter()
        .fold((0.0, 0.0), |(w, m), (rho, j)| {
            (w + j - level, m + (j - level) * rho)
        });
    let rho = if weight > 0.0 {
        moment / weight
    } else {
        curve[top].0
    };
    Some(Step { rho, jump })
}

/// How far from the circle's centre the points a blurred sample averages lie: sorted, with
/// their running sums.
#[derive(Debug, Clone)]
struct SampleRadii {
    radii: Vec<f64>,
    running: Vec<f64>,
}

impl SampleRadii {
    /// The sample `rho_px` along the ray in `(cos, sin)`, blurred by `blur`.
    fn new(rho_px: f64, (cos, sin): (f64, f64), blur: &BoxBlur) -> Self {
        let mut radii: Vec<f64> = blur
            .offsets
            .iter()
            .map(|(u, v)| (rho_px + u * cos + v * sin).hypot(v * cos - u * sin))
            .collect();
        radii.sort_by(f64::total_cmp);
        let running = std::iter::once(0.0)
            .chain(radii.iter().scan(0.0, |sum, r| {
                *sum += r;
                Some(*sum)
            }))
            .collect();
        Self { radii, running }
    }

    /// The model's four terms for a step at radius `rho`, averaged over the blur: inside's
    /// 1 and t, outside's 1 and t (t = radius − rho).
    fn basis(&self, rho: f64) -> [f64; 4] {
        let n = self.radii.len().max(1) as f64;
        let inside = self.radii.partition_point(|r| *r < rho);
        let total = self.running.last().copied().unwrap_or(0.0);
        let below = self.running[inside];
        let share = inside as f64 / n;
        [
            share,
            (below - rho * inside as f64) / n,
            1.0 - share,
            (total - below - rho * (self.radii.len() - inside) as f64) / n,
        ]
    }
}

/// The jump of the least-squares fit of `rows` (each the model's terms at a sample and the
/// sample's channels): per channel `p + q t` inside and `u + v t` outside; the jump is the
/// length of (p − u) over the channels. `None` when the terms do not determine it.
fn jump_at(rows: impl Iterator<Item = ([f64; 4], [f64; 3])>) -> Option<f64> {
    let mut ata = [[0.0f64; 4]; 4];
    let mut atb = [[0.0f64; 4]; 3];
    for (phi, col) in rows {
        for r in 0..4 {
            for c in 0..4 {
                ata[r][c] += phi[r] * phi[c];
            }
            for (b, v) in atb.iter_mut().zip(col) {
                b[r] += phi[r] * v;
            }
        }
    }
    let inv = invert4(ata)?;
    let jump2: f64 = atb
        .iter()
        .map(|b| {
            let coef = |r: usize| (0..4).map(|c| inv[r][c] * b[c]).sum::<f64>();
            (coef(0) - coef(2)).powi(2)
        })
        .sum();
    Some(jump2.sqrt())
}

/// The inverse of a 4×4 matrix by Gauss–Jordan elimination with partial pivoting; `None`
/// when it is singular.
fn invert4(m: [[f64; 4]; 4]) -> Option<[[f64; 4]; 4]> {
    let mut a = m;
    let mut inv = [[0.0; 4]; 4];
    for (i, row) in inv.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    let scale = m.iter().flatten().fold(0.0f64, |s, v| s.max(v.abs()));
    for col in 0..4 {
        let pivot = (col..4).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))?;
        let size = a[pivot][col].abs();
        if size.is_nan() || size <= 1e-12 * scale {
            return None;
        }
        a.swap(col, pivot);
        inv.swap(col, pivot);
        let p = a[col][col];
        for c in 0..4 {
            a[col][c] /= p;
            inv[col][c] /= p;
        }
        for r in (0..4).filter(|&r| r != col) {
            let f = a[r][col];
            for c in 0..4 {
                a[r][c] -= f * a[col][c];
                inv[r][c] -= f * inv[col][c];
            }
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ray across a straight rim far from the centre: `inside` sloping by `slope` per px
    /// up to `edge_px`, zero beyond, box-blurred `blur` px wide, sampled every half pixel.
    fn ray(edge_px: f64, inside: [f64; 3], slope: f64, blur: f64) -> Vec<[f64; 3]> {
        (0..120)
            .map(|i| {
                let rho = i as f64 * 0.5;
                let n = 200;
                let mut acc = [0.0; 3];
                for k in 0..n {
                    let t = rho - 0.5 * blur + blur * (k as f64 + 0.5) / n as f64;
                    if t < edge_px {
                        for c in 0..3 {
                            acc[c] += (inside[c] + slope * (t - edge_px)) / n as f64;
                        }
                    }
                }
                acc
            })
            .collect()
    }

    fn fit(colours: &[[f64; 3]], range: (f64, f64)) -> Option<Step> {
        let blur = BoxBlur::new(2);
        // Along y: a box's offsets across the ray then lie along x, and a rim 1000 px out
        // from the centre is straight across the box.
        let shifted: Vec<[f64; 3]> = std::iter::repeat_n([0.0; 3], 2000)
            .chain(colours.iter().copied())
            .collect();
        let ray = RaySamples {
            colours: &shifted,
            step_px: 0.5,
            direction: (0.0, 1.0),
            blur: &blur,
        };
        fit_step(ray, (range.0 + 1000.0, range.1 + 1000.0), blur.width_px()).map(|s| Step {
            rho: s.rho - 1000.0,
            ..s
        })
    }

    #[test]
    fn a_blurred_step_is_found_where_it_is_whatever_the_slope_inside() {
        for (edge, slope) in [(30.0, 0.0), (30.3, 2.0), (29.7, -3.0)] {
            let colours = ray(edge, [20.0, -10.0, 5.0], slope, 5.0);
            let s = fit(&colours, (edge - 5.0, edge + 5.0)).expect("step");
            assert!((s.rho - edge).abs() < 0.25, "{edge} {slope}: {s:?}");
            assert!(
                (s.jump - 525f64.sqrt()).abs() < 1.0,
                "{edge} {slope}: {s:?}"
            );
        }
        // A camera that blurs as much again as the detector moves it by less than a third
        // of a pixel.
        let colours = ray(30.25, [20.0, -10.0, 5.0], 1.0, 8.0);
        let s = fit(&colours, (25.0, 35.0)).expect("step");
        assert!((s.rho - 30.25).abs() < 0.3, "{s:?}");
    }

    #[test]
    fn no_window_no_step() {
        let colours = ray(10.0, [20.0, 0.0, 0.0], 0.0, 5.0);
        let blur = BoxBlur::new(2);
        fn samples<'a>(colours: &'a [[f64; 3]], blur: &'a BoxBlur) -> RaySamples<'a> {
            RaySamples {
                colours,
                step_px: 0.5,
                direction: (1.0, 0.0),
                blur,
            }
        }
        assert!(fit_step(samples(&colours, &blur), (f64::NAN, 3.0), 5.0).is_none());
        assert!(fit_step(samples(&colours, &blur), (4.0, 3.0), 5.0).is_none());
        assert!(fit_step(samples(&colours[..8], &blur), (1.0, 3.0), 5.0).is_none());
        let flat = [[0.0; 3]; 40];
        assert!(fit_step(samples(&flat, &blur), (5.0, 15.0), 5.0).is_none_or(|s| s.jump < 1e-9));
    }
}
