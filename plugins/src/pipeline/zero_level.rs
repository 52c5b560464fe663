//! The DCT's zero level: its Neumann solve leaves the depth free by a constant, and the
//! gradients' small bias integrates into a tilt across the window. Zero depth is a plane
//! through the window's sides that lie inside the image (the margin around the contact),
//! fitted in least squares: the tilt goes with it, and a contact's skirt no longer rises
//! above the noise threshold on one side and sinks on the other (docs/pipeline.md, "Depth
//! solvers"). A side on the image's edge may cut through a contact that runs off the pad,
//! so it is not used. The plane is tilted only where two opposite sides are inside, so
//! that it spans the window between them; otherwise (a window at a corner or along an
//! edge of the image) zero is the inside sides' mean, as a level: a tilt extrapolated from
//! two sides meeting at a corner lifts the far corner's noise over the contact threshold
//! (untouched frames read contact there).

/// A plane `offset + slope_x·x + slope_y·y` over the window's pixels (window coordinates).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct ZeroPlane {
    offset: f64,
    slope_x: f64,
    slope_y: f64,
}

impl ZeroPlane {
    /// The plane's depth at pixel `(x, y)` of the window.
    pub(super) fn at(&self, x: usize, y: usize) -> f32 {
        (self.offset + self.slope_x * x as f64 + self.slope_y * y as f64) as f32
    }

    /// Take the plane away from `depth` (`w` wide, row-major).
    pub(super) fn subtract_from(&self, depth: &mut [f32], w: usize) {
        for (y, row) in depth.chunks_exact_mut(w.max(1)).enumerate() {
            for (x, d) in row.iter_mut().enumerate() {
                *d -= self.at(x, y);
            }
        }
    }
}

/// The plane through the window's sides that lie inside the image (not on its edge),
/// tilted only when two opposite sides are among them (their mean level otherwise);
/// `None` when the window spans the whole image.
pub(super) fn sides_plane(
    depth: &[f32],
    (x0, y0, w, h): (usize, usize, usize, usize),
    (width, height): (usize, usize),
) -> Option<ZeroPlane> {
    let sides = [x0 > 0, x0 + w < width, y0 > 0, y0 + h < height];
    let [left, right, top, bottom] = sides;
    plane_through(depth, (w, h), sides, (left && right) || (top && bottom))
}

/// The mean level of the whole border of a `w × h` depth (the noise calibration's
/// no-contact frames), level; zero for an empty one. Not tilted: the contact threshold
/// measured on these frames must cover a window whose zero is only a level (at a corner or
/// along an edge of the image), and a tilted zero here set it too low for those (untouched
/// frames read contact at a corner).
pub(super) fn border_level(depth: &[f32], w: usize, h: usize) -> ZeroPlane {
    plane_through(depth, (w, h), [true; 4], false).unwrap_or_default()
}

/// How deep into the window a tilted plane's sides reach, px: its two slopes are fitted to
/// this many rows and columns along each side (the level alone, to the outermost), so the
/// camera's noise on a one-pixel side does not tilt it (at 5× the nominal noise a held
/// finger's force wandered by 10% with one-pixel sides). Within the window's margin
/// (`WINDOW_MARGIN_PX`, 8 px beyond the active blocks).
const TILT_SIDE_PX: usize = 4;

/// Least squares over the pixels of the sides `[left, right, top, bottom]` marked, each
/// once; with `slopes`, over [`TILT_SIDE_PX`] along each side, and a slope is fitted where
/// the sides reach over at least half the window across it; without, over the outermost
/// pixels, only the level (their mean). Non-finite depths are left out.
fn plane_through(
    depth: &[f32],
    (w, h): (usize, usize),
    [left, right, top, bottom]: [bool; 4],
    slopes: bool,
) -> Option<ZeroPlane> {
    let reach = if slopes { TILT_SIDE_PX } else { 1 };
    // Only the sides are visited: the left's columns, then the right's (none twice).
    let left_end = if left { reach.min(w) } else { 0 };
    let right_start = if right {
        w.saturating_sub(reach).max(left_end)
    } else {
        w
    };
    let mut sums = PlaneSums::default();
    for (y, row) in depth.chunks_exact(w.max(1)).take(h).enumerate() {
        if (top && y < reach) || (bottom && y + reach >= h) {
            for (x, v) in row.iter().enumerate() {
                sums.add(x, y, *v);
            }
            continue;
        }
        for x in (0..left_end).chain(right_start..w) {
            sums.add(x, y, row[x]);
        }
    }
    sums.solve(w, h, slopes)
}

fn finite_or_zero(v: f64) -> f64 {
    if v.is_finite() { v } else { 0.0 }
}

/// The normal equations' sums of a plane fit.
#[derive(Debug, Default)]
struct PlaneSums {
    n: f64,
    x: f64,
    y: f64,
    xx: f64,
    xy: f64,
    yy: f64,
    z: f64,
    xz: f64,
    yz: f64,
    x_span: (usize, usize),
    y_span: (usize, usize),
}

impl PlaneSums {
    fn add(&mut self, x: usize, y: usize, z: f32) {
        if !z.is_finite() {
            return;
        }
        if self.n == 0.0 {
            self.x_span = (x, x);
            self.y_span = (y, y);
        }
        self.x_span = (self.x_span.0.min(x), self.x_span.1.max(x));
        self.y_span = (self.y_span.0.min(y), self.y_span.1.max(y));
        let (xf, yf, zf) = (x as f64, y as f64, f64::from(z));
        self.n += 1.0;
        self.x += xf;
        self.y += yf;
        self.xx += xf * xf;
        self.xy += xf * yf;
        self.yy += yf * yf;
        self.z += zf;
        self.xz += xf * zf;
        self.yz += yf * zf;
    }

    /// The plane, with (when `slopes`) a slope along x (y) only where the pixels span at
    /// least half the window's width (height) and more than one column (row).
    fn solve(&self, w: usize, h: usize, slopes: bool) -> Option<ZeroPlane> {
        if self.n == 0.0 {
            return None;
        }
        let spans = |(a, b): (usize, usize), n: usize| b > a && 2 * (b - a + 1) >= n;
        let fit_x = slopes && spans(self.x_span, w);
        let fit_y = slopes && spans(self.y_span, h);
        // Centred sums: the slopes from the 2×2 (or 1×1) covariance system.
        let (mx, my, mz) = (self.x / self.n, self.y / self.n, self.z / self.n);
        let sxx = self.xx - self.n * mx * mx;
        let syy = self.yy - self.n * my * my;
        let sxy = self.xy - self.n * mx * my;
        let sxz = self.xz - self.n * mx * mz;
        let syz = self.yz - self.n * my * mz;
        let (slope_x, slope_y) = match (fit_x, fit_y) {
            (true, true) => {
                let det = sxx * syy - sxy * sxy;
                if det.abs() > 1e-9 * (sxx * syy).max(1e-300) {
                    ((sxz * syy - syz * sxy) / det, (syz * sxx - sxz * sxy) / det)
                } else {
                    (sxz / sxx, 0.0)
                }
            }
            (true, false) => (sxz / sxx, 0.0),
            (false, true) => (0.0, syz / syy),
            (false, false) => (0.0, 0.0),
        };
        let (slope_x, slope_y) = (finite_or_zero(slope_x), finite_or_zero(slope_y));
        Some(ZeroPlane {
            offset: finite_or_zero(mz - slope_x * mx - slope_y * my),
            slope_x,
            slope_y,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tilted(w: usize, h: usize, bump: bool) -> Vec<f32> {
        (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                let (dx, dy) = (x as f64 - w as f64 / 2.0, y as f64 - h as f64 / 2.0);
                let cap = if bump {
                    (0.09 * (w * h) as f64 - dx * dx - dy * dy).max(0.0)
                } else {
                    0.0
                };
                (0.3 + 0.02 * x as f64 - 0.05 * y as f64 + cap) as f32
            })
            .collect()
    }

    #[test]
    fn a_tilt_through_the_inside_sides_is_taken_away_and_the_contact_kept() {
        let (w, h) = (40, 30);
        let mut d = tilted(w, h, true);
        let plane = sides_plane(&d, (5, 5, w, h), (100, 100)).expect("inside sides");
        plane.subtract_from(&mut d, w);
        for (x, y) in [(0, 0), (39, 0), (0, 29), (39, 29), (3, 17)] {
            assert!(d[y * w + x].abs() < 1e-4, "({x}, {y}): {}", d[y * w + x]);
        }
        assert!(
            d[15 * w + 20] > 100.0,
            "the contact stays: {}",
            d[15 * w + 20]
        );
    }

    #[test]
    fn a_tilt_needs_two_opposite_sides_and_no_side_gives_no_plane() {
        let (w, h) = (40, 30);
        let d = tilted(w, h, false);
        // Top and bottom inside, left and right on the image's edges: the whole tilt.
        let plane = sides_plane(&d, (0, 5, w, h), (w, 40)).expect("top and bottom");
        assert!((plane.slope_x - 0.02).abs() < 1e-6, "{plane:?}");
        assert!((plane.slope_y + 0.05).abs() < 1e-6, "{plane:?}");
        assert!((plane.at(0, 0) - 0.3).abs() < 1e-5);
        // Top and right only (a corner): their mean, level.
        let corner = sides_plane(&d, (0, 5, w, h), (w + 5, 5 + h)).expect("top and right");
        assert_eq!((corner.slope_x, corner.slope_y), (0.0, 0.0));
        let sides: Vec<f32> = (0..w)
            .map(|x| d[x])
            .chain((1..h).map(|y| d[y * w + w - 1]))
            .collect();
        let mean = sides.iter().map(|v| f64::from(*v)).sum::<f64>() / sides.len() as f64;
        assert!(
            (f64::from(corner.at(7, 9)) - mean).abs() < 1e-5,
            "{corner:?} vs {mean}"
        );
        assert_eq!(sides_plane(&d, (0, 0, w, h), (w, h)), None);
    }

    #[test]
    fn degenerate_windows_and_bad_values_give_a_finite_plane() {
        for (w, h) in [(1, 1), (1, 7), (7, 1), (2, 2)] {
            let mut d = tilted(w, h, false);
            d[0] = f32::NAN;
            for window in [(3, 3, w, h), (0, 3, w, h), (3, 0, w, h)] {
                if let Some(p) = sides_plane(&d, window, (20, 20)) {
                    assert!(p.offset.is_finite() && p.slope_x.is_finite() && p.slope_y.is_finite());
                }
            }
            let p = border_level(&d, w, h);
            assert!(p.at(w - 1, h - 1).is_finite(), "{w}x{h}: {p:?}");
        }
        let extreme = vec![1e30f32; 12];
        assert!(border_level(&extreme, 4, 3).at(3, 2).is_finite());
        assert_eq!(border_level(&[], 0, 0).at(0, 0), 0.0);
    }

    /// The side walk visits exactly the pixels within its reach of an inside side, each
    /// once, for every side pattern and for windows one pixel wide or high: its level is
    /// their mean, as a pass over every pixel of the window finds it.
    #[test]
    fn the_sides_walked_are_the_inside_sides_each_pixel_once() {
        let brute = |d: &[f32], (w, h): (usize, usize), sides: [bool; 4], reach: usize| {
            let (mut sum, mut n) = (0.0f64, 0usize);
            for y in 0..h {
                for x in 0..w {
                    let on = [x < reach, x + reach >= w, y < reach, y + reach >= h];
                    if on.iter().zip(&sides).any(|(o, s)| *o && *s) {
                        sum += f64::from(d[y * w + x]);
                        n += 1;
                    }
                }
            }
            (n > 0).then(|| sum / n as f64)
        };
        for (w, h) in [(1, 1), (1, 7), (7, 1), (2, 2), (5, 6), (13, 9), (40, 30)] {
            let d: Vec<f32> = (0..w * h).map(|k| ((k * 37 % 101) as f32) / 7.0).collect();
            for bits in 0..16u8 {
                let sides = [0, 1, 2, 3].map(|b| bits & (1 << b) != 0);
                for (slopes, reach) in [(false, 1), (true, TILT_SIDE_PX)] {
                    let walked = plane_through(&d, (w, h), sides, slopes).map(|p| {
                        // Without slopes the offset is the mean; with them, the fitted
                        // plane's mean over the same pixels is the mean too.
                        let mut sums = PlaneSums::default();
                        for y in 0..h {
                            for x in 0..w {
                                let on = [x < reach, x + reach >= w, y < reach, y + reach >= h];
                                if on.iter().zip(&sides).any(|(o, s)| *o && *s) {
                                    sums.add(x, y, p.at(x, y));
                                }
                            }
                        }
                        sums.z / sums.n
                    });
                    let expected = brute(&d, (w, h), sides, reach);
                    match (walked, expected) {
                        (Some(a), Some(b)) => {
                            assert!((a - b).abs() < 1e-4, "{w}x{h} {sides:?} {slopes}: {a} {b}")
                        }
                        (a, b) => assert_eq!(a.is_some(), b.is_some(), "{w}x{h} {sides:?}"),
                    }
                }
            }
        }
    }
}
