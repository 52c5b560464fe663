//! The ball as the truth of a reconstruction: the radius of a sphere fitted to the
//! reconstructed surface of a press, to compare with the ball's (`calibrate eval`'s
//! `sphere_radius_mm`, docs/calibration.md, "The sphere check").
//!
//! The fit is algebraic least squares: the sphere x² + y² + z² + D x + E y + F z + G = 0
//! (centre (−D/2, −E/2, −F/2), radius² = (D² + E² + F²)/4 − G) that minimises the sum of
//! squared residuals of that equation over the points, solved by Householder QR on the
//! points centred on their mean and scaled by their RMS spread (so a shallow cap of a few
//! hundred pixels stays well conditioned). It is exact for points on a sphere. Points on a
//! plane, fewer than four points, or any non-finite coordinate give no sphere.

/// Share of a press's peak depth above which a surface point enters the fit: the deeper
/// part of the contact, away from the rim where the gel bends away from the ball.
pub const SPHERE_DEPTH_SHARE: f64 = 0.25;

/// A column is taken as dependent on the others when its norm after the earlier
/// reflections falls below this share of its original norm (points on a plane or a line).
const RANK_TOLERANCE: f64 = 1e-9;

/// A fitted sphere, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre `[x, y, z]`, mm.
    pub centre_mm: [f64; 3],
    /// Radius, mm.
    pub radius_mm: f64,
}

/// The algebraic least-squares sphere through `points` (`[x, y, z]`, mm); `None` for fewer
/// than 4 points, a non-finite coordinate, points on a plane (or a line), or a fit whose
/// radius is not a positive finite number.
pub fn fit_sphere(points: &[[f64; 3]]) -> Option<Sphere> {
    if points.len() < 4 || points.iter().flatten().any(|v| !v.is_finite()) {
        return None;
    }
    let n = points.len() as f64;
    let mean = [0, 1, 2].map(|c| points.iter().map(|p| p[c]).sum::<f64>() / n);
    let spread = (points
        .iter()
        .map(|p| (0..3).map(|c| (p[c] - mean[c]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / n)
        .sqrt();
    if !(spread.is_finite() && spread > 0.0) {
        return None;
    }
    // Rows [u, v, w, 1] · [D, E, F, G] = −(u² + v² + w²) in the scaled coordinates.
    let mut a = Vec::with_capacity(points.len() * 4);
    let mut b = Vec::with_capacity(points.len());
    for p in points {
        let q = [0, 1, 2].map(|c| (p[c] - mean[c]) / spread);
        a.extend_from_slice(&[q[0], q[1], q[2], 1.0]);
        b.push(-(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]));
    }
    let [d, e, f, g] = least_squares_4(&mut a, &mut b)?;
    let radius2 = (d * d + e * e + f * f) / 4.0 - g;
    let radius_mm = radius2.sqrt() * spread;
    let centre_mm = [
        mean[0] - d / 2.0 * spread,
        mean[1] - e / 2.0 * spread,
        mean[2] - f / 2.0 * spread,
    ];
    (radius2 > 0.0 && radius_mm.is_finite() && centre_mm.iter().all(|c| c.is_finite())).then_some(
        Sphere {
            centre_mm,
            radius_mm,
        },
    )
}

/// Least squares `min |A x − b|` for `A` of 4 columns (row-major, `b.len()` rows) by
/// Householder QR, in place; `None` when a column depends on the others.
fn least_squares_4(a: &mut [f64], b: &mut [f64]) -> Option<[f64; 4]> {
    let rows = b.len();
    let norm0: [f64; 4] = [0, 1, 2, 3].map(|c| column_norm(a, rows, c, 0));
    for k in 0..4 {
        let norm = column_norm(a, rows, k, k);
        // (NaN compares false: refused too.)
        if norm.partial_cmp(&(RANK_TOLERANCE * norm0[k])) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        // v = x − α e₁ with α = −sign(x₀) |x|, so that no cancellation occurs.
        let alpha = if a[k * 4 + k] > 0.0 { -norm } else { norm };
        a[k * 4 + k] -= alpha;
        let vnorm2: f64 = (k..rows).map(|r| a[r * 4 + k] * a[r * 4 + k]).sum();
        if vnorm2.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        for c in k + 1..4 {
            let dot: f64 = (k..rows).map(|r| a[r * 4 + k] * a[r * 4 + c]).sum();
            let s = 2.0 * dot / vnorm2;
            (k..rows).for_each(|r| a[r * 4 + c] -= s * a[r * 4 + k]);
        }
        let dot: f64 = (k..rows).map(|r| a[r * 4 + k] * b[r]).sum();
        let s = 2.0 * dot / vnorm2;
        (k..rows).for_each(|r| b[r] -= s * a[r * 4 + k]);
        a[k * 4 + k] = alpha;
    }
    // Back substitution on R (the upper triangle of the first four rows).
    let mut x = [0.0; 4];
    for k in (0..4).rev() {
        let tail: f64 = (k + 1..4).map(|c| a[k * 4 + c] * x[c]).sum();
        x[k] = (b[k] - tail) / a[k * 4 + k];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Norm of column `c` of the 4-column matrix `a` over rows `from..rows`.
fn column_norm(a: &[f64], rows: usize, c: usize, from: usize) -> f64 {
    (from..rows)
        .map(|r| a[r * 4 + c] * a[r * 4 + c])
        .sum::<f64>()
        .sqrt()
}

/// The radius of the sphere fitted to one reconstructed press, mm: the surface points of
/// `depth_px` (`width` wide, depth in px, positive into the gel) deeper than
/// [`SPHERE_DEPTH_SHARE`] of its peak, at `(x, y) = (column, row) × mm_per_px` and
/// `z = depth × mm_per_px`. `None` when the peak is not positive or the fit has no sphere.
pub fn press_sphere_radius_mm(depth_px: &[f64], width: usize, mm_per_px: f64) -> Option<f64> {
    let peak = depth_px
        .iter()
        .copied()
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max);
    if !(peak > 0.0 && width > 0 && mm_per_px.is_finite() && mm_per_px > 0.0) {
        return None;
    }
    let points: Vec<[f64; 3]> = depth_px
        .iter()
        .enumerate()
        .filter(|(_, d)| d.is_finite() && **d > SPHERE_DEPTH_SHARE * peak)
        .map(|(p, d)| {
            [
                (p % width) as f64 * mm_per_px,
                (p / width) as f64 * mm_per_px,
                d * mm_per_px,
            ]
        })
        .collect();
    fit_sphere(&points).map(|s| s.radius_mm)
}

/// The median of the finite values (`None` when there is none).
pub fn median(values: impl IntoIterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        (v[m - 1] + v[m]) / 2.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cap of a sphere of radius `r` around `(cx, cy)` on a `step`-mm grid, `depth` mm
    /// deep: z = sqrt(r² − ρ²) − (r − depth) where that is positive.
    fn cap(r: f64, (cx, cy): (f64, f64), depth: f64, step: f64) -> Vec<[f64; 3]> {
        let mut out = Vec::new();
        for i in -60..=60 {
            for j in -60..=60 {
                let (x, y) = (cx + f64::from(i) * step, cy + f64::from(j) * step);
                let rho2 = (x - cx).powi(2) + (y - cy).powi(2);
                let z = (r * r - rho2).max(0.0).sqrt() - (r - depth);
                if rho2 < r * r && z > 0.0 {
                    out.push([x, y, z]);
                }
            }
        }
        out
    }

    #[test]
    fn an_exact_cap_of_radius_2_mm_gives_2_mm() {
        for (depth, step) in [(0.5, 0.0625), (0.1, 0.0625), (1.5, 0.05)] {
            let points = cap(2.0, (9.7, 7.3), depth, step);
            assert!(points.len() > 20, "{depth}: {} points", points.len());
            let s = fit_sphere(&points).expect("a sphere");
            assert!(
                (s.radius_mm - 2.0).abs() / 2.0 < 1e-6,
                "depth {depth}: radius {}",
                s.radius_mm
            );
            let want = [9.7, 7.3, depth - 2.0];
            for (got, want) in s.centre_mm.iter().zip(want) {
                assert!((got - want).abs() < 1e-6, "{:?}", s.centre_mm);
            }
        }
    }

    #[test]
    fn a_depth_map_of_a_cap_gives_its_radius() {
        // A 3 mm ball 0.4 mm deep on a 0.05 mm grid, as depth in px.
        let (w, h, mm) = (120usize, 100usize, 0.05);
        let (r, d, cx, cy) = (3.0f64, 0.4f64, 3.1f64, 2.4f64);
        let depth_px: Vec<f64> = (0..w * h)
            .map(|p| {
                let (x, y) = ((p % w) as f64 * mm, (p / w) as f64 * mm);
                let rho2 = (x - cx).powi(2) + (y - cy).powi(2);
                ((r * r - rho2).max(0.0).sqrt() - (r - d)).max(0.0) / mm
            })
            .collect();
        let radius = press_sphere_radius_mm(&depth_px, w, mm).expect("a radius");
        assert!((radius - r).abs() / r < 1e-6, "{radius}");
        // A wrong pixel size scales x and y but not the depth's share: not 3 mm.
        let off = press_sphere_radius_mm(&depth_px, w, mm * 1.2).expect("a radius");
        assert!((off - r).abs() > 0.1, "{off}");
    }

    #[test]
    fn degenerate_points_give_no_sphere() {
        assert_eq!(fit_sphere(&[]), None);
        let three = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.2]];
        assert_eq!(fit_sphere(&three), None);
        // A flat patch, a tilted plane, a line, one point repeated.
        let flat: Vec<[f64; 3]> = (0..100)
            .map(|i| [f64::from(i % 10), f64::from(i / 10), 0.3])
            .collect();
        assert_eq!(fit_sphere(&flat), None);
        let tilted: Vec<[f64; 3]> = flat
            .iter()
            .map(|p| [p[0], p[1], 0.2 * p[0] - 0.1 * p[1] + 1.0])
            .collect();
        assert_eq!(fit_sphere(&tilted), None);
        let line: Vec<[f64; 3]> = (0..20).map(|i| [f64::from(i); 3]).collect();
        assert_eq!(fit_sphere(&line), None);
        assert_eq!(fit_sphere(&[[1.0, 2.0, 3.0]; 10]), None);
        // Any NaN or infinity.
        let mut cap = cap(2.0, (0.0, 0.0), 0.5, 0.1);
        cap[7][2] = f64::NAN;
        assert_eq!(fit_sphere(&cap), None);
        cap[7][2] = f64::INFINITY;
        assert_eq!(fit_sphere(&cap), None);
        // Depth maps: all zero, all NaN, negative.
        assert_eq!(press_sphere_radius_mm(&[0.0; 64], 8, 0.1), None);
        assert_eq!(press_sphere_radius_mm(&[f64::NAN; 64], 8, 0.1), None);
        assert_eq!(press_sphere_radius_mm(&[-1.0; 64], 8, 0.1), None);
        assert_eq!(press_sphere_radius_mm(&[1.0; 64], 8, f64::NAN), None);
    }

    #[test]
    fn noisy_and_odd_points_stay_finite() {
        // Nearly flat noisy points: a sphere or none, never NaN or infinity.
        let mut seed = 7u64;
        let mut noise = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for _ in 0..50 {
            let pts: Vec<[f64; 3]> = (0..40)
                .map(|i| [f64::from(i % 8), f64::from(i / 8), 1e-3 * noise()])
                .collect();
            if let Some(s) = fit_sphere(&pts) {
                assert!(s.radius_mm.is_finite() && s.radius_mm > 0.0, "{s:?}");
                assert!(s.centre_mm.iter().all(|c| c.is_finite()), "{s:?}");
            }
        }
    }

    #[test]
    fn median_of_finite_values() {
        assert_eq!(median([3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median([4.0, 1.0, 2.0, 3.0]), Some(2.5));
        assert_eq!(median([f64::NAN, 5.0]), Some(5.0));
        assert_eq!(median(std::iter::empty()), None);
    }
}
