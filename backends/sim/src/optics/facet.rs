//! What a camera pixel sees of the gel: its slope, and how much of it the contact covers.
//!
//! A camera pixel averages the light from its whole footprint. Away from a contact's rim
//! the surface under a pixel is one smooth slope, and the central differences of the depth
//! map give it. At the rim the depth is the pressed surface cut off at zero: the slope jumps
//! from the object's to flat within one pixel. Central differences there mix the two into
//! half a slope on both sides of the rim, a pixel wide each way, and shading that half
//! slope makes the imprint look wider than the contact (by about half a pixel through the
//! LEDs' non-linear response: `gelgrip bench label`, docs/calibration.md). So at the rim a
//! pixel's slope is read from the pressed side only, the pressed surface is continued
//! across the pixel as a plane, and the share of the footprint where that plane lies
//! below the gel (is pressed) is the pixel's coverage: the pixel sees `coverage` of the
//! slope's light and the rest of the flat gel's.

use crate::scene::HeightMap;

/// A pixel's view of the gel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Facet {
    /// The pressed surface's slope under the pixel, depth (mm) per mm along x.
    pub gx: f64,
    /// Along y.
    pub gy: f64,
    /// Share of the pixel's footprint that the pressed surface covers, 0–1.
    pub coverage: f64,
}

/// Sub-samples of a pixel's footprint each way where the rim crosses it.
const FOOTPRINT_SAMPLES: usize = 8;

/// The facet at pixel (`x`, `y`) of `map` (pixels `mm_per_px` wide).
pub fn facet(map: &HeightMap, x: usize, y: usize, mm_per_px: f64) -> Facet {
    let (w, h) = (map.width_px, map.height_px);
    let depth = |x: isize, y: isize| -> f64 {
        if x < 0 || y < 0 || x as usize >= w || y as usize >= h {
            return 0.0;
        }
        f64::from(map.depth_mm[y as usize * w + x as usize])
    };
    let (xi, yi) = (x as isize, y as isize);
    let here = depth(xi, yi);
    // The plane of the pressed surface: its depth at the pixel's centre (negative where the
    // centre is not pressed) and its slope, mm per pixel.
    let (level, (sx, sy)) = if here > 0.0 {
        (here, pressed_slope(&depth, xi, yi))
    } else {
        let deepest = NEIGHBOURS
            .iter()
            .map(|&(dx, dy)| (depth(xi + dx, yi + dy), dx, dy))
            .filter(|n| n.0 > 0.0)
            .max_by(|a, b| a.0.total_cmp(&b.0));
        let Some((d, dx, dy)) = deepest else {
            return Facet {
                gx: 0.0,
                gy: 0.0,
                coverage: 0.0,
            };
        };
        let (sx, sy) = pressed_slope(&depth, xi + dx, yi + dy);
        // Continued from that neighbour to this centre; the map says this centre is not
        // pressed, so the plane is at most at the gel's surface here.
        ((d - sx * dx as f64 - sy * dy as f64).min(0.0), (sx, sy))
    };
    Facet {
        gx: sx / mm_per_px,
        gy: sy / mm_per_px,
        coverage: coverage(level, sx, sy),
    }
}

/// The eight neighbours of a pixel.
const NEIGHBOURS: [(isize, isize); 8] = [
    (-1, 0),
    (1, 0),
    (0, -1),
    (0, 1),
    (-1, -1),
    (1, -1),
    (-1, 1),
    (1, 1),
];

/// The slope at pressed pixel (`x`, `y`), mm per pixel, from pressed samples only: central
/// differences where both neighbours along an axis are pressed, one-sided towards the
/// pressed one where one is, none where neither is.
fn pressed_slope(depth: &impl Fn(isize, isize) -> f64, x: isize, y: isize) -> (f64, f64) {
    let here = depth(x, y);
    let axis = |before: f64, after: f64| match (before > 0.0, after > 0.0) {
        (true, true) => 0.5 * (after - before),
        (false, true) => after - here,
        (true, false) => here - before,
        (false, false) => 0.0,
    };
    (
        axis(depth(x - 1, y), depth(x + 1, y)),
        axis(depth(x, y - 1), depth(x, y + 1)),
    )
}

/// Share of the pixel's footprint (a unit square about its centre) where the plane
/// `level + sx·u + sy·v` is above zero (pressed).
fn coverage(level: f64, sx: f64, sy: f64) -> f64 {
    let reach = 0.5 * (sx.abs() + sy.abs());
    if !(level.is_finite() && reach.is_finite()) {
        return if level > 0.0 { 1.0 } else { 0.0 };
    }
    if level - reach > 0.0 {
        return 1.0;
    }
    if level + reach <= 0.0 {
        return 0.0;
    }
    let n = FOOTPRINT_SAMPLES;
    let at = |i: usize| (i as f64 + 0.5) / n as f64 - 0.5;
    let inside = (0..n)
        .flat_map(|i| (0..n).map(move |j| (at(i), at(j))))
        .filter(|(u, v)| level + sx * u + sy * v > 0.0)
        .count();
    inside as f64 / (n * n) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn away_from_a_rim_a_facet_is_the_central_difference() {
        let mut map = HeightMap::flat(8, 8);
        for y in 0..8 {
            for x in 0..8 {
                map.depth_mm[y * 8 + x] = 1.0 + 0.1 * x as f32 - 0.05 * y as f32;
            }
        }
        let f = facet(&map, 4, 4, 0.5);
        assert!(
            (f.gx - 0.2).abs() < 1e-6 && (f.gy + 0.1).abs() < 1e-6,
            "{f:?}"
        );
        assert_eq!(f.coverage, 1.0);
        let flat = facet(&HeightMap::flat(4, 4), 2, 2, 0.5);
        assert_eq!((flat.gx, flat.gy, flat.coverage), (0.0, 0.0, 0.0));
    }

    #[test]
    fn at_a_rim_the_pressed_side_covers_its_share_of_the_pixel() {
        // Depth 0.3·(4.25 − x) mm: the rim at x = 4.25, a quarter into pixel 4's footprint
        // from its centre.
        let mut map = HeightMap::flat(8, 3);
        for y in 0..3 {
            for x in 0..8 {
                map.depth_mm[y * 8 + x] = (0.3 * (4.25 - x as f64)).max(0.0) as f32;
            }
        }
        let inside = facet(&map, 4, 1, 1.0);
        assert!((inside.gx + 0.3).abs() < 1e-6, "{inside:?}");
        assert!((inside.coverage - 0.75).abs() < 0.07, "{inside:?}");
        let outside = facet(&map, 5, 1, 1.0);
        assert!((outside.gx + 0.3).abs() < 1e-6, "{outside:?}");
        assert_eq!(outside.coverage, 0.0);
        let deep = facet(&map, 2, 1, 1.0);
        assert!(
            (deep.gx + 0.3).abs() < 1e-6 && deep.coverage == 1.0,
            "{deep:?}"
        );
    }
}
