//! What presses on each sensor: indentation height maps (depth into the gel, mm).
//!
//! Until scene physics arrives, the scene is a built-in static press per sensor: a ball of
//! the configured diameter pressed to the configured depth, at a position that differs from
//! sensor to sensor so the views are distinguishable.

use std::sync::Mutex;

/// Depth into the gel per pixel, row-major, in mm. Its buffer goes back to a bounded spare
/// list when it is dropped, for the next map of its size.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightMap {
    /// Columns.
    pub width_px: usize,
    /// Rows.
    pub height_px: usize,
    /// Depth per pixel, mm (≥ 0).
    pub depth_mm: Vec<f32>,
}

/// Frame-sized depth buffers of dropped maps, kept for the next maps of their size: a
/// scene's pads give a map per capture, and allocating each afresh (300 KB at 320×240)
/// leaves the allocator's heap to fragment over a long run (docs/architecture.md, "Memory
/// over a long run").
static SPARE_DEPTHS: Mutex<Vec<Vec<f32>>> = Mutex::new(Vec::new());

/// At most this many spare buffers are kept (the pads of a few captures in flight); more
/// are freed.
const SPARE_DEPTHS_KEPT: usize = 32;

/// Maps smaller than this many pixels are left to the allocator.
const SPARE_DEPTHS_MIN_PX: usize = 16 * 1024;

/// A zeroed buffer of `n` depths, a spare one when there is one of that size.
fn zeroed_depths(n: usize) -> Vec<f32> {
    let spare = (n >= SPARE_DEPTHS_MIN_PX)
        .then(|| SPARE_DEPTHS.lock().ok())
        .flatten()
        .and_then(|mut spare| {
            let i = spare.iter().position(|v| v.capacity() == n)?;
            Some(spare.swap_remove(i))
        });
    match spare {
        Some(mut depth) => {
            depth.clear();
            depth.resize(n, 0.0);
            depth
        }
        None => vec![0.0; n],
    }
}

impl Drop for HeightMap {
    fn drop(&mut self) {
        let depth = std::mem::take(&mut self.depth_mm);
        if depth.capacity() < SPARE_DEPTHS_MIN_PX {
            return;
        }
        if let Ok(mut spare) = SPARE_DEPTHS.lock()
            && spare.len() < SPARE_DEPTHS_KEPT
        {
            spare.push(depth);
        }
    }
}

impl HeightMap {
    /// A flat, untouched gel.
    pub fn flat(width_px: usize, height_px: usize) -> Self {
        Self {
            width_px,
            height_px,
            depth_mm: zeroed_depths(width_px * height_px),
        }
    }

    /// A ball of `diameter_mm` pressed `depth_mm` deep, centred at (`cx_px`, `cy_px`).
    pub fn ball_press(
        width_px: usize,
        height_px: usize,
        mm_per_px: f64,
        (cx_px, cy_px): (f64, f64),
        diameter_mm: f64,
        depth_mm: f64,
    ) -> Self {
        Self::round_press((width_px, height_px), diameter_mm, depth_mm, |x, y| {
            let (dx, dy) = ((x - cx_px) * mm_per_px, (y - cy_px) * mm_per_px);
            dx * dx + dy * dy
        })
    }

    /// A cylinder of `diameter_mm` lying on the pad, pressed `depth_mm` deep, its axis
    /// through (`cx_px`, `cy_px`) at `axis_deg` from the image x axis (towards y). It runs
    /// across the whole pad, as a handle or a bottle held in a grasp does.
    pub fn cylinder_press(
        (width_px, height_px): (usize, usize),
        mm_per_px: f64,
        (cx_px, cy_px): (f64, f64),
        axis_deg: f64,
        diameter_mm: f64,
        depth_mm: f64,
    ) -> Self {
        let (sin, cos) = axis_deg.to_radians().sin_cos();
        Self::round_press((width_px, height_px), diameter_mm, depth_mm, |x, y| {
            let rho = ((y - cy_px) * cos - (x - cx_px) * sin) * mm_per_px;
            rho * rho
        })
    }

    /// A press by a round surface of `diameter_mm` (a ball or a cylinder's side) `depth_mm`
    /// deep, where `rho2_mm2(x, y)` is the square of pixel (x, y)'s distance from its centre
    /// or axis, mm²: the surface lies `r − sqrt(r² − ρ²)` above its lowest point.
    fn round_press(
        (width_px, height_px): (usize, usize),
        diameter_mm: f64,
        depth_mm: f64,
        rho2_mm2: impl Fn(f64, f64) -> f64,
    ) -> Self {
        let mut map = Self::flat(width_px, height_px);
        let r = diameter_mm / 2.0;
        let depth = depth_mm.clamp(0.0, r);
        for y in 0..height_px {
            for x in 0..width_px {
                let rho2 = rho2_mm2(x as f64, y as f64);
                if rho2 < r * r {
                    let d = depth - (r - (r * r - rho2).sqrt());
                    if d > 0.0 {
                        map.depth_mm[y * width_px + x] = d as f32;
                    }
                }
            }
        }
        map
    }

    /// The built-in press of sensor `index`.
    pub fn builtin_press(
        index: usize,
        width_px: usize,
        height_px: usize,
        mm_per_px: f64,
        diameter_mm: f64,
        depth_mm: f64,
    ) -> Self {
        // Spread press centres over the pad with a golden-angle walk.
        let angle = index as f64 * 2.399_963;
        let rx = width_px as f64 * 0.2;
        let ry = height_px as f64 * 0.2;
        let cx = width_px as f64 / 2.0 + rx * angle.cos();
        let cy = height_px as f64 / 2.0 + ry * angle.sin();
        Self::ball_press(
            width_px,
            height_px,
            mm_per_px,
            (cx, cy),
            diameter_mm,
            depth_mm,
        )
    }

    /// Deepest point, mm.
    pub fn max_depth_mm(&self) -> f32 {
        self.depth_mm.iter().copied().fold(0.0, f32::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cylinder_press_is_a_band_of_the_contact_width() {
        // Axis along x through the centre: 2·sqrt(2·r·d − d²) wide, the same in every column.
        let m = HeightMap::cylinder_press((320, 240), 0.0625, (160.0, 120.0), 0.0, 40.0, 0.2);
        assert!((m.max_depth_mm() - 0.2).abs() < 1e-3);
        let width_mm = 2.0 * (2.0f64 * 20.0 * 0.2 - 0.04).sqrt();
        for x in [0, 100, 319] {
            let rows = (0..240).filter(|y| m.depth_mm[y * 320 + x] > 0.0).count() as f64;
            assert!(
                (rows * 0.0625 - width_mm).abs() < 0.13,
                "column {x}: {rows} rows"
            );
        }
        // Turned a right angle: the same band along y.
        let t = HeightMap::cylinder_press((320, 240), 0.0625, (160.0, 120.0), 90.0, 40.0, 0.2);
        let cols = (0..320).filter(|x| t.depth_mm[120 * 320 + x] > 0.0).count() as f64;
        assert!((cols * 0.0625 - width_mm).abs() < 0.13, "{cols} columns");
        assert!(t.depth_mm.iter().all(|d| d.is_finite() && *d >= 0.0));
    }

    #[test]
    fn ball_press_has_the_right_depth_and_contact_radius() {
        let m = HeightMap::ball_press(320, 240, 0.0625, (160.0, 120.0), 6.0, 0.5);
        assert!((m.max_depth_mm() - 0.5).abs() < 1e-3);
        // contact radius sqrt(r² − (r − d)²) = sqrt(9 − 6.25) = 1.658 mm = 26.5 px
        let inside = m.depth_mm.iter().filter(|d| **d > 0.0).count() as f64;
        let expected = std::f64::consts::PI * 26.53f64.powi(2);
        assert!(
            (inside - expected).abs() / expected < 0.03,
            "{inside} vs {expected}"
        );
    }

    #[test]
    fn zero_depth_is_flat() {
        let m = HeightMap::ball_press(32, 24, 0.1, (16.0, 12.0), 6.0, 0.0);
        assert_eq!(m.max_depth_mm(), 0.0);
    }
}
