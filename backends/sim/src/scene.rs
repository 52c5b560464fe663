//! What presses on each sensor: indentation height maps (depth into the gel, mm).
//!
//! Until scene physics arrives, the scene is a built-in static press per sensor: a ball of
//! the configured diameter pressed to the configured depth, at a position that differs from
//! sensor to sensor so the views are distinguishable.

/// Depth into the gel per pixel, row-major, in mm.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightMap {
    /// Columns.
    pub width_px: usize,
    /// Rows.
    pub height_px: usize,
    /// Depth per pixel, mm (≥ 0).
    pub depth_mm: Vec<f32>,
}

impl HeightMap {
    /// A flat, untouched gel.
    pub fn flat(width_px: usize, height_px: usize) -> Self {
        Self {
            width_px,
            height_px,
            depth_mm: vec![0.0; width_px * height_px],
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
        let mut map = Self::flat(width_px, height_px);
        let r = diameter_mm / 2.0;
        let depth = depth_mm.clamp(0.0, r);
        for y in 0..height_px {
            for x in 0..width_px {
                let dx = (x as f64 - cx_px) * mm_per_px;
                let dy = (y as f64 - cy_px) * mm_per_px;
                let rho2 = dx * dx + dy * dy;
                if rho2 < r * r {
                    // Sphere surface below the gel plane: depth − (r − sqrt(r² − ρ²)).
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
