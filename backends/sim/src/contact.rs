//! Contact between a gel pad and the scene object: indentation, normal force and the
//! height map the renderer draws.
//!
//! The gel is a Winkler foundation: pressure is [`GEL_N_PER_MM3`] per mm of indentation, and
//! ten times stiffer past its [`GEL_THICKNESS_MM`] (the pad bottoms out). A compliant object
//! gives way uniformly under each pad by `x = F / k_object`, so the gel takes the
//! penetration minus `x`; `x` solves `F_gel(x) = k_object·x` by bisection. Mechanics use a
//! coarse grid over the pad ([`PadGrid`], about 1 mm); frames use every pixel, computed only
//! inside the coarse contact's bounding box.

use glam::DVec3;

use crate::finger::{PadFrame, PadLoad};
use crate::scene::HeightMap;

/// Gel foundation stiffness: pressure per mm of indentation, N/mm³.
pub const GEL_N_PER_MM3: f64 = 0.08;
/// Gel thickness, mm; deeper indentation meets the stiff backing.
pub const GEL_THICKNESS_MM: f64 = 2.5;
/// Stiffness multiplier of the backing past the gel thickness.
const BACKING_FACTOR: f64 = 10.0;
/// Coarse samples across the longer pad side.
const GRID_LONG: usize = 16;

/// Pressure for an indentation, N/mm².
pub fn pressure_n_per_mm2(depth_mm: f64) -> f64 {
    if depth_mm <= 0.0 {
        0.0
    } else if depth_mm <= GEL_THICKNESS_MM {
        GEL_N_PER_MM3 * depth_mm
    } else {
        GEL_N_PER_MM3 * (GEL_THICKNESS_MM + BACKING_FACTOR * (depth_mm - GEL_THICKNESS_MM))
    }
}

/// What the object looks like to a pad: signed distance (mm, negative inside) and which
/// part (0 = body, 1 = trigger) is nearest.
pub trait Surface {
    /// Distance and part at `p` (gripper frame).
    fn probe(&self, p: DVec3) -> (f64, u8);
    /// Bounding sphere (centre, radius) in the gripper frame.
    fn bounds(&self) -> (DVec3, f64);
    /// Local contact stiffness, N/mm (`None` = rigid).
    fn stiffness_n_per_mm(&self) -> Option<f64>;
}

/// A pad's size and sampling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PadGrid {
    /// Image columns.
    pub width_px: usize,
    /// Image rows.
    pub height_px: usize,
    /// Pixel size, mm.
    pub mm_per_px: f64,
}

impl PadGrid {
    fn half_extent_mm(&self) -> (f64, f64) {
        (
            self.width_px as f64 * self.mm_per_px / 2.0,
            self.height_px as f64 * self.mm_per_px / 2.0,
        )
    }

    fn coarse(&self) -> (usize, usize) {
        let long = self.width_px.max(self.height_px).max(1) as f64;
        let cols = ((self.width_px as f64 / long) * GRID_LONG as f64)
            .ceil()
            .max(1.0) as usize;
        let rows = ((self.height_px as f64 / long) * GRID_LONG as f64)
            .ceil()
            .max(1.0) as usize;
        (cols, rows)
    }

    /// Gripper-frame point of image position (`x_px`, `y_px`).
    fn point(&self, frame: &PadFrame, x_px: f64, y_px: f64) -> DVec3 {
        frame.center
            + frame.ex * ((x_px - self.width_px as f64 / 2.0) * self.mm_per_px)
            + frame.ey * ((y_px - self.height_px as f64 / 2.0) * self.mm_per_px)
    }
}

/// The result of one pad's contact.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PadContact {
    /// Normal force, N, and its centre of pressure.
    pub load: PadLoad,
    /// Force on the trigger part alone, N.
    pub trigger_force_n: f64,
    /// Area in contact with the trigger part, mm².
    pub trigger_area_mm2: f64,
    /// Deepest gel indentation, mm.
    pub max_depth_mm: f64,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Indentation volume, mm³.
    pub volume_mm3: f64,
    /// How far the object gave way under this pad, mm.
    pub object_deflection_mm: f64,
    /// Bounding box of the coarse contact, image px (x0, y0, x1, y1); empty when no contact.
    pub bbox_px: Option<(usize, usize, usize, usize)>,
}

struct Sample {
    x_px: f64,
    y_px: f64,
    penetration_mm: f64,
    point: DVec3,
    part: u8,
}

fn may_touch(frame: &PadFrame, grid: &PadGrid, surface: &dyn Surface) -> bool {
    let (hx, hy) = grid.half_extent_mm();
    let (c, r) = surface.bounds();
    (c - frame.center).length() <= r + (hx * hx + hy * hy).sqrt() + 1e-6
}

/// The object's deflection under a pad whose samples penetrate by `pens` (each over
/// `cell_mm2`).
fn deflection_mm(pens: &[f64], cell_mm2: f64, stiffness: Option<f64>) -> f64 {
    let Some(k) = stiffness else {
        return 0.0;
    };
    let force = |x: f64| -> f64 {
        pens.iter()
            .map(|p| pressure_n_per_mm2(p - x) * cell_mm2)
            .sum()
    };
    let (mut lo, mut hi) = (0.0, pens.iter().copied().fold(0.0, f64::max));
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if force(mid) > k * mid {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Contact of the pad at `frame` with `surface`.
pub fn pad_contact(frame: &PadFrame, grid: &PadGrid, surface: &dyn Surface) -> PadContact {
    if !may_touch(frame, grid, surface) {
        return PadContact::default();
    }
    let (cols, rows) = grid.coarse();
    let step_x = grid.width_px as f64 / cols as f64;
    let step_y = grid.height_px as f64 / rows as f64;
    let cell_mm2 = step_x * step_y * grid.mm_per_px * grid.mm_per_px;
    let mut samples = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let x_px = (c as f64 + 0.5) * step_x;
            let y_px = (r as f64 + 0.5) * step_y;
            let point = grid.point(frame, x_px, y_px);
            let (d, part) = surface.probe(point);
            if d < 0.0 && d.is_finite() {
                samples.push(Sample {
                    x_px,
                    y_px,
                    penetration_mm: -d,
                    point,
                    part,
                });
            }
        }
    }
    if samples.is_empty() {
        return PadContact::default();
    }
    let pens: Vec<f64> = samples.iter().map(|s| s.penetration_mm).collect();
    let x = deflection_mm(&pens, cell_mm2, surface.stiffness_n_per_mm());
    let mut out = PadContact {
        object_deflection_mm: x,
        ..PadContact::default()
    };
    let mut moment = DVec3::ZERO;
    let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, 0.0f64, 0.0f64);
    for s in &samples {
        let depth = s.penetration_mm - x;
        if depth <= 0.0 {
            continue;
        }
        let f = pressure_n_per_mm2(depth) * cell_mm2;
        let rate = if depth <= GEL_THICKNESS_MM {
            GEL_N_PER_MM3
        } else {
            GEL_N_PER_MM3 * BACKING_FACTOR
        };
        out.load.stiffness_n_per_mm += rate * cell_mm2;
        out.load.force_n += f;
        moment += s.point * f;
        out.area_mm2 += cell_mm2;
        out.volume_mm3 += depth.min(GEL_THICKNESS_MM) * cell_mm2;
        out.max_depth_mm = out.max_depth_mm.max(depth.min(GEL_THICKNESS_MM));
        if s.part == 1 {
            out.trigger_force_n += f;
            out.trigger_area_mm2 += cell_mm2;
        }
        x0 = x0.min(s.x_px - step_x);
        y0 = y0.min(s.y_px - step_y);
        x1 = x1.max(s.x_px + step_x);
        y1 = y1.max(s.y_px + step_y);
    }
    if let Some(k) = surface.stiffness_n_per_mm() {
        // The gel and the object in series.
        let pad = out.load.stiffness_n_per_mm;
        out.load.stiffness_n_per_mm = if pad + k > 0.0 {
            pad * k / (pad + k)
        } else {
            0.0
        };
    }
    if out.load.force_n > 0.0 {
        out.load.point = moment / out.load.force_n;
        out.bbox_px = Some((
            x0.max(0.0) as usize,
            y0.max(0.0) as usize,
            (x1.ceil() as usize).min(grid.width_px),
            (y1.ceil() as usize).min(grid.height_px),
        ));
    }
    out
}

/// Pixel stride of the exact samples of [`height_map`]; pixels between are bilinear.
const MAP_STRIDE: usize = 2;

/// Exact samples covering pixels `lo..hi` at [`MAP_STRIDE`] (the last pixel included).
fn samples_between(lo: usize, hi: usize) -> usize {
    (hi - 1 - lo).div_ceil(MAP_STRIDE) + 1
}

/// Pixel of sample `i` over `lo..hi`.
fn sample_px(i: usize, lo: usize, hi: usize) -> usize {
    (lo + i * MAP_STRIDE).min(hi - 1)
}

/// The samples either side of pixel `p` in `lo..hi`, and `p`'s share of the way between.
fn bracket(p: usize, lo: usize, hi: usize) -> (usize, usize, f64) {
    let n = samples_between(lo, hi);
    let i0 = ((p - lo) / MAP_STRIDE).min(n - 1);
    let i1 = (i0 + 1).min(n - 1);
    let (a, b) = (sample_px(i0, lo, hi), sample_px(i1, lo, hi));
    let t = if b > a {
        ((p - a) as f64 / (b - a) as f64).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (i0, i1, t)
}

/// The full-resolution gel indentation of a pad, given its coarse `contact`. The object's
/// distance is probed every `MAP_STRIDE` (2) pixels inside the contact's bounding box and
/// interpolated bilinearly between (the indentation is smooth at that scale).
pub fn height_map(
    frame: &PadFrame,
    grid: &PadGrid,
    surface: &dyn Surface,
    contact: &PadContact,
) -> HeightMap {
    let mut map = HeightMap::flat(grid.width_px, grid.height_px);
    let Some((x0, y0, x1, y1)) = contact.bbox_px else {
        return map;
    };
    if x1 <= x0 || y1 <= y0 {
        return map;
    }
    let depth_at = |x: usize, y: usize| -> f64 {
        let p = grid.point(frame, x as f64 + 0.5, y as f64 + 0.5);
        let d = (-surface.probe(p).0 - contact.object_deflection_mm).clamp(0.0, GEL_THICKNESS_MM);
        if d.is_finite() { d } else { 0.0 }
    };
    let cols = samples_between(x0, x1);
    let rows = samples_between(y0, y1);
    let coarse: Vec<f64> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| (c, r)))
        .map(|(c, r)| depth_at(sample_px(c, x0, x1), sample_px(r, y0, y1)))
        .collect();
    for y in y0..y1 {
        let (r0, r1, ty) = bracket(y, y0, y1);
        for x in x0..x1 {
            let (c0, c1, tx) = bracket(x, x0, x1);
            let v = |r: usize, c: usize| coarse[r * cols + c];
            let top = v(r0, c0) * (1.0 - tx) + v(r0, c1) * tx;
            let bottom = v(r1, c0) * (1.0 - tx) + v(r1, c1) * tx;
            map.depth_mm[y * grid.width_px + x] = (top * (1.0 - ty) + bottom * ty) as f32;
        }
    }
    map
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Ball {
        center: DVec3,
        radius: f64,
        stiffness: Option<f64>,
    }

    impl Surface for Ball {
        fn probe(&self, p: DVec3) -> (f64, u8) {
            ((p - self.center).length() - self.radius, 0)
        }
        fn bounds(&self) -> (DVec3, f64) {
            (self.center, self.radius)
        }
        fn stiffness_n_per_mm(&self) -> Option<f64> {
            self.stiffness
        }
    }

    fn pad() -> (PadFrame, PadGrid) {
        (
            PadFrame {
                center: DVec3::ZERO,
                normal: DVec3::Z,
                ex: DVec3::X,
                ey: DVec3::Y,
            },
            PadGrid {
                width_px: 320,
                height_px: 240,
                mm_per_px: 0.0625,
            },
        )
    }

    fn ball(depth: f64, stiffness: Option<f64>) -> Ball {
        Ball {
            center: DVec3::new(0.0, 0.0, 10.0 - depth),
            radius: 10.0,
            stiffness,
        }
    }

    #[test]
    fn no_penetration_no_force() {
        let (f, g) = pad();
        let c = pad_contact(&f, &g, &ball(-0.1, None));
        assert_eq!(c, PadContact::default());
        let far = Ball {
            center: DVec3::new(500.0, 0.0, 0.0),
            radius: 1.0,
            stiffness: None,
        };
        assert_eq!(pad_contact(&f, &g, &far), PadContact::default());
    }

    #[test]
    fn a_rigid_ball_gives_the_winkler_force_and_matching_height_map() {
        let (f, g) = pad();
        let depth = 0.8;
        let c = pad_contact(&f, &g, &ball(depth, None));
        // Winkler: F = k ∫ (d − ρ²/2R) dA = k π R d² (paraboloid), 0.08·π·10·0.64 = 1.61 N.
        let expected = GEL_N_PER_MM3 * std::f64::consts::PI * 10.0 * depth * depth;
        assert!((c.load.force_n - expected).abs() / expected < 0.15, "{c:?}");
        assert!((c.max_depth_mm - depth).abs() < 0.1);
        assert!(c.load.point.x.abs() < 0.3 && c.load.point.y.abs() < 0.3);
        let map = height_map(&f, &g, &ball(depth, None), &c);
        assert!((f64::from(map.max_depth_mm()) - depth).abs() < 0.01);
        let px_mm2 = g.mm_per_px * g.mm_per_px;
        let volume: f64 = map.depth_mm.iter().map(|d| f64::from(*d) * px_mm2).sum();
        // Spherical cap: π d² (3R − d) / 3.
        let v_exact = std::f64::consts::PI * depth * depth * (30.0 - depth) / 3.0;
        assert!(
            (volume - v_exact).abs() / v_exact < 0.05,
            "{volume} vs {v_exact}"
        );
    }

    #[test]
    fn a_soft_object_gives_way_and_the_force_balances() {
        let (f, g) = pad();
        let soft = ball(1.0, Some(2.0));
        let c = pad_contact(&f, &g, &soft);
        assert!(c.object_deflection_mm > 0.1);
        assert!(
            (c.load.force_n - 2.0 * c.object_deflection_mm).abs() < 0.1,
            "{c:?}"
        );
        let rigid = pad_contact(&f, &g, &ball(1.0, None));
        assert!(c.load.force_n < rigid.load.force_n);
    }

    #[test]
    fn bottoming_out_is_stiffer_and_stays_finite() {
        let (f, g) = pad();
        let shallow = pad_contact(&f, &g, &ball(2.0, None)).load.force_n;
        let deep = pad_contact(&f, &g, &ball(4.0, None));
        assert!(deep.load.force_n > 4.0 * shallow);
        assert!(deep.max_depth_mm <= GEL_THICKNESS_MM);
        let map = height_map(
            &f,
            &g,
            &ball(9.0, None),
            &pad_contact(&f, &g, &ball(9.0, None)),
        );
        assert!(map.depth_mm.iter().all(|d| d.is_finite() && *d >= 0.0));
    }
}
