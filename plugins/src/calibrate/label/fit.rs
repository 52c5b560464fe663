//! Least-squares circles through rim points: the algebraic (Kåsa) fit, refitted without the
//! points far off the first circle.

/// A fitted circle and how far its points lie off it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// Centre x, px.
    pub cx: f64,
    /// Centre y, px.
    pub cy: f64,
    /// Radius, px.
    pub r: f64,
    /// RMS distance of the kept points from the circle, px.
    pub rms: f64,
}

/// Fewest points a circle is fitted through.
const MIN_POINTS: usize = 5;

/// The Kåsa fit: minimises Σ (x² + y² + D x + E y + F)², solved in coordinates centred on
/// the points' mean. `None` for fewer than [`MIN_POINTS`] points or collinear ones.
pub fn kasa(points: &[(f64, f64)]) -> Option<Circle> {
    if points.len() < MIN_POINTS {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (mut suu, mut svv, mut suv, mut suuu, mut svvv, mut suvv, mut svuu) =
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (x, y) in points {
        let (u, v) = (x - mx, y - my);
        suu += u * u;
        svv += v * v;
        suv += u * v;
        suuu += u * u * u;
        svvv += v * v * v;
        suvv += u * v * v;
        svuu += v * u * u;
    }
    let det = suu * svv - suv * suv;
    if det.is_nan() || det.abs() <= 1e-9 * (suu * svv).max(1e-12) {
        return None;
    }
    let b1 = 0.5 * (suuu + suvv);
    let b2 = 0.5 * (svvv + svuu);
    let uc = (b1 * svv - b2 * suv) / det;
    let vc = (suu * b2 - suv * b1) / det;
    let r = (uc * uc + vc * vc + (suu + svv) / n).sqrt();
    let (cx, cy) = (uc + mx, vc + my);
    let rms = (points
        .iter()
        .map(|(x, y)| ((x - cx).hypot(y - cy) - r).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let c = Circle { cx, cy, r, rms };
    [cx, cy, r, rms].iter().all(|v| v.is_finite()).then_some(c)
}

/// [`kasa`], then again without the points more than 2.5 × the median distance (at least
/// 0.5 px) off the first circle.
pub fn robust_circle(points: &[(f64, f64)]) -> Option<Circle> {
    let first = kasa(points)?;
    let off = |(x, y): &(f64, f64)| ((x - first.cx).hypot(y - first.cy) - first.r).abs();
    let mut d: Vec<f64> = points.iter().map(off).collect();
    d.sort_by(f64::total_cmp);
    let limit = (2.5 * d[d.len() / 2]).max(0.5);
    let kept: Vec<(f64, f64)> = points.iter().copied().filter(|p| off(p) <= limit).collect();
    kasa(&kept).or(Some(first))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_circle_and_drops_an_outlier() {
        let mut pts: Vec<(f64, f64)> = (0..36)
            .map(|k| {
                let a = k as f64 * 10f64.to_radians();
                (40.0 + 12.5 * a.cos(), 30.0 + 12.5 * a.sin())
            })
            .collect();
        let c = kasa(&pts).expect("circle");
        assert!((c.cx - 40.0).abs() < 1e-9 && (c.cy - 30.0).abs() < 1e-9);
        assert!((c.r - 12.5).abs() < 1e-9 && c.rms < 1e-9);
        pts.push((80.0, 30.0));
        let c = robust_circle(&pts).expect("circle");
        assert!(
            (c.cx - 40.0).abs() < 1e-6 && (c.r - 12.5).abs() < 1e-6,
            "{c:?}"
        );
        assert!(kasa(&pts[..3]).is_none());
        let line: Vec<(f64, f64)> = (0..10).map(|i| (i as f64, 2.0 * i as f64)).collect();
        assert!(kasa(&line).is_none());
    }
}
