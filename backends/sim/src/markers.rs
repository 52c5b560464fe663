//! Markers on a simulated gel: the layout's grid of dark dots (`markers`), drawn where the
//! gel's surface carries them, so that shear shows in the image as it does on a real
//! marker gel (docs/sim.md, "Markers").
//!
//! The dots sit on a square grid centred on the pad. Each is a disc of ink whose
//! anti-aliased coverage of a pixel darkens the light the gel returns there to
//! [`INK_ALBEDO`] of itself, before the camera's noise and JPEG, as printed ink on a lit
//! gel does. Under a contact carrying tangential load the surface moves ([`GelShear`]:
//! the contact's Cattaneo–Mindlin shift along the load's direction in the image), and each
//! dot with it, by the shift at its place at rest.

use gelgrip_controller::markers::MarkerGrid;

use crate::traction::Traction;

/// Share of the light a dot's ink returns (a dark print on a white-ish gel).
pub const INK_ALBEDO: f64 = 0.25;

/// The gel's shear on one pad: where the contact's centre is and which way its surface
/// moves, in the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GelShear {
    /// The contact's centre of pressure, image px.
    pub centre_px: (f64, f64),
    /// Unit direction the surface moves along, image px (x along columns, y along rows).
    pub direction: (f64, f64),
    /// The contact's tangential state.
    pub traction: Traction,
}

impl GelShear {
    /// How far the surface at `(x, y)` px has moved, px along x and y, at `mm_per_px`.
    pub fn shift_px(&self, (x, y): (f64, f64), mm_per_px: f64) -> (f64, f64) {
        let r_mm = (x - self.centre_px.0).hypot(y - self.centre_px.1) * mm_per_px;
        let shift = self.traction.surface_shift_mm(r_mm) / mm_per_px;
        if !shift.is_finite() {
            return (0.0, 0.0);
        }
        (shift * self.direction.0, shift * self.direction.1)
    }
}

/// One pad's dots, in image px, and their ink at rest.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerDots {
    width: usize,
    height: usize,
    mm_per_px: f64,
    /// Dot centres at rest, px.
    centres: Vec<(f64, f64)>,
    radius_px: f64,
    /// Ink coverage of every pixel at rest (0–1, row-major).
    rest: Vec<f32>,
}

impl MarkerDots {
    /// The dots of `grid` on a `width` × `height` pad of `mm_per_px`.
    pub fn new(grid: &MarkerGrid, width: usize, height: usize, mm_per_px: f64) -> Self {
        let pitch_px = grid.pitch_mm / mm_per_px;
        let radius_px = 0.5 * grid.dot_mm / mm_per_px;
        let (cx, cy) = (width as f64 / 2.0, height as f64 / 2.0);
        let along = |centre: f64, size: usize| {
            let n = ((centre + radius_px) / pitch_px).floor() as i64;
            (-n..=n)
                .map(move |k| centre + k as f64 * pitch_px)
                .filter(move |v| *v + radius_px > 0.0 && *v - radius_px < size as f64)
        };
        let centres: Vec<(f64, f64)> = along(cy, height)
            .flat_map(|y| along(cx, width).map(move |x| (x, y)))
            .collect();
        let mut dots = Self {
            width,
            height,
            mm_per_px,
            centres,
            radius_px,
            rest: vec![0.0; width * height],
        };
        let mut rest = std::mem::take(&mut dots.rest);
        dots.paint(None, &mut rest, &mut Vec::new());
        dots.rest = rest;
        dots
    }

    /// The dots' count.
    pub fn len(&self) -> usize {
        self.centres.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }

    /// Dot centres at rest, px.
    pub fn centres(&self) -> &[(f64, f64)] {
        &self.centres
    }

    /// The share of light pixel `(x, y)` returns at rest (1 off the dots).
    pub fn rest_factor(&self, x: usize, y: usize) -> f64 {
        let ink = self.rest.get(y * self.width + x).copied().unwrap_or(0.0);
        1.0 - f64::from(ink) * (1.0 - INK_ALBEDO)
    }

    /// The ink of the dots moved by `shear` (at rest without) into `ink` (a `width` ×
    /// `height` plane, zero where no dot is: the caller clears the pixels listed), and every
    /// pixel a dot may cover at rest or moved into `touched` (once per dot box; a pixel in
    /// two boxes is listed twice).
    pub fn paint(&self, shear: Option<&GelShear>, ink: &mut [f32], touched: &mut Vec<usize>) {
        let r = self.radius_px;
        for &(x, y) in &self.centres {
            let (dx, dy) = shear.map_or((0.0, 0.0), |s| s.shift_px((x, y), self.mm_per_px));
            let (mx, my) = (x + dx, y + dy);
            // The box around the dot at rest and moved: the pixels that may change.
            let x0 = (x.min(mx) - r - 1.0).floor().max(0.0) as usize;
            let y0 = (y.min(my) - r - 1.0).floor().max(0.0) as usize;
            let x1 = ((x.max(mx) + r + 1.0).ceil().max(0.0) as usize).min(self.width);
            let y1 = ((y.max(my) + r + 1.0).ceil().max(0.0) as usize).min(self.height);
            for py in y0..y1 {
                for px in x0..x1 {
                    let p = py * self.width + px;
                    touched.push(p);
                    // Pixel centres at integers + 0.5 (the shader's facets are too).
                    let d = (px as f64 + 0.5 - mx).hypot(py as f64 + 0.5 - my);
                    let cover = (r + 0.5 - d).clamp(0.0, 1.0) as f32;
                    if let Some(v) = ink.get_mut(p) {
                        *v = v.max(cover);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GRID: MarkerGrid = MarkerGrid {
        pitch_mm: 1.2,
        dot_mm: 0.45,
    };

    #[test]
    fn the_dots_sit_on_a_grid_centred_on_the_pad_and_cover_their_area() {
        let dots = MarkerDots::new(&GRID, 320, 240, 0.0625);
        // 19.2 px apart: 17 columns and 13 rows reach into a 320 × 240 pad.
        assert_eq!(dots.len(), 17 * 13);
        assert!(dots.centres().contains(&(160.0, 120.0)));
        let covered: f64 = dots.rest.iter().map(|v| f64::from(*v)).sum();
        let area = std::f64::consts::PI * (0.5 * 0.45 / 0.0625f64).powi(2);
        let whole = dots
            .centres()
            .iter()
            .filter(|(x, y)| *x > 5.0 && *y > 5.0 && *x < 315.0 && *y < 235.0)
            .count();
        assert!(
            covered > 0.97 * area * whole as f64,
            "{covered} of {}",
            area * whole as f64
        );
        assert!((dots.rest_factor(160, 120) - INK_ALBEDO).abs() < 1e-9);
        assert_eq!(dots.rest_factor(170, 120), 1.0);
    }

    #[test]
    fn shear_moves_the_dots_under_the_contact_along_the_load() {
        let dots = MarkerDots::new(&GRID, 320, 240, 0.0625);
        let shear = GelShear {
            centre_px: (160.0, 120.0),
            direction: (1.0, 0.0),
            traction: Traction::new(1.0, 0.5, 0.9, 2.0),
        };
        let (dx, dy) = shear.shift_px((160.0, 120.0), 0.0625);
        assert!((dx - shear.traction.shift_mm / 0.0625).abs() < 1e-9 && dy == 0.0);
        let mut ink = vec![0.0f32; 320 * 240];
        let mut touched = Vec::new();
        dots.paint(Some(&shear), &mut ink, &mut touched);
        // The centre dot moved right by dx: ink ahead of it, none left behind.
        let at = |x: f64| ink[120 * 320 + x as usize];
        assert_eq!(at(160.0 + dx), 1.0);
        assert_eq!(at(160.0 - 3.7), 0.0);
        assert!(touched.contains(&(120 * 320 + 160)));
        // Far from the contact the dots stay put.
        let (far, _) = shear.shift_px((10.0, 10.0), 0.0625);
        assert!(far.abs() < 0.25 * dx);
    }
}
