//! Fitting [`RealisticParams`] to a real sensor's frames, and the statistics the fit and
//! docs/calibration.md compare: the background's channel means and falloff across the pad
//! (4×3 tile means), and around the presses the colour response (mean difference from the
//! background per channel in 8 sectors × 6 rings around each contact centre: five inside
//! the contact and the halo around it; the contact's first harmonic: amplitude and the
//! azimuth it peaks at), and the pixel noise away from them.
//!
//! The fit: the background polynomial by least squares on the real background
//! ([`fit_background`]); the reflectance, shadowing, crosstalk, gamma and the presses'
//! geometry (a ball radius in px, since the real data has no ball size; the share of each
//! labelled contact the ball touches; the gel's skirt, [`crate::gel`]; or held where the
//! labels were found for a known ball, [`GeometryFit::Held`]) by coordinate descent on the
//! sector means of noise-free renders at the real contacts and, with a [`FitTarget`]
//! response, on what a table trained on their pixels reads
//! ([`crate::optics::response`]; [`fit_presses`]); the noise is the real frames'
//! ([`PressStats::noise_rgb`]).

use super::realistic::{BACKGROUND_TERMS, RealisticParams, RealisticShader, background_basis};
use super::response::{ResponseCurve, model_pixels};
use crate::gel::BallOnGel;
use crate::unit::UnitVariation;

/// The real Mini presses' geometry as fitted with [`crate::optics::realistic::MINI`] (the
/// data has no ball size), px at 640×480: a sharp rim at the labelled contact.
pub const MINI_PRESSES: PressGeometry = PressGeometry {
    ball_radius_px: 58.0,
    contact_share: 1.0,
    skirt_px: 0.0,
};

/// The same fitted with [`crate::optics::realistic::MINI_GEL`]: the ball touches 0.466 of
/// each labelled contact's radius and the gel's skirt (54 px, 1.71 mm) makes the rest of
/// the visible imprint and the halo around it.
pub const MINI_GEL_PRESSES: PressGeometry = PressGeometry {
    ball_radius_px: 60.3,
    contact_share: 0.466,
    skirt_px: 54.0,
};

/// The real Mini's pixel size, mm (gs_sdk's 0.0317 mm/px at 640×480): turns the fitted
/// skirt into [`RealisticParams::skirt_mm`].
pub const MINI_MM_PER_PX: f64 = 0.0317;

/// An interleaved 8-bit RGB image.
#[derive(Debug, Clone, Copy)]
pub struct Image<'a> {
    /// Columns.
    pub width_px: usize,
    /// Rows.
    pub height_px: usize,
    /// `width_px × height_px × 3` bytes.
    pub rgb: &'a [u8],
}

impl Image<'_> {
    pub(crate) fn at(&self, x: usize, y: usize, c: usize) -> f64 {
        f64::from(self.rgb[(y * self.width_px + x) * 3 + c])
    }
}

/// A labelled contact: centre and radius, px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Centre, px.
    pub center_x_px: f64,
    /// Centre, px.
    pub center_y_px: f64,
    /// Contact radius, px.
    pub radius_px: f64,
}

/// Tiles across and down of [`BackgroundStats::tiles_rgb`].
pub const TILES: (usize, usize) = (4, 3);

/// A background's statistics.
#[derive(Debug, Clone, PartialEq)]
pub struct BackgroundStats {
    /// Mean per channel, grey levels.
    pub mean_rgb: [f64; 3],
    /// Mean per channel of each of the [`TILES`] tiles, row by row.
    pub tiles_rgb: Vec<[f64; 3]>,
}

impl BackgroundStats {
    /// Per channel: the darkest tile's mean over the brightest's (1: no falloff).
    pub fn falloff_rgb(&self) -> [f64; 3] {
        [0, 1, 2].map(|c| {
            let v = self.tiles_rgb.iter().map(|t| t[c]);
            let lo = v.clone().fold(f64::INFINITY, f64::min);
            let hi = v.fold(0.0, f64::max);
            if hi > 0.0 { lo / hi } else { 1.0 }
        })
    }
}

/// [`BackgroundStats`] of `img`.
pub fn background_stats(img: Image<'_>) -> BackgroundStats {
    let (w, h) = (img.width_px, img.height_px);
    let (tx, ty) = TILES;
    let mut tiles = vec![([0.0; 3], 0usize); tx * ty];
    let mut all = [0.0; 3];
    for y in 0..h {
        for x in 0..w {
            let t = (y * ty / h.max(1)) * tx + x * tx / w.max(1);
            for (c, (tile, sum)) in tiles[t].0.iter_mut().zip(&mut all).enumerate() {
                let v = img.at(x, y, c);
                *tile += v;
                *sum += v;
            }
            tiles[t].1 += 1;
        }
    }
    let n = (w * h).max(1) as f64;
    BackgroundStats {
        mean_rgb: all.map(|s| s / n),
        tiles_rgb: tiles
            .into_iter()
            .map(|(s, n)| s.map(|v| v / n.max(1) as f64))
            .collect(),
    }
}

/// Sectors around a contact's centre (sector k is centred on azimuth k × 45°).
pub const SECTORS: usize = 8;
/// Rings around a contact's centre: [`CONTACT_RINGS`] inside the contact, whose outer
/// edges are [`RING_EDGES`] (shares of the contact radius: on a ball's cap each ring is a
/// band of slopes, finest at the rim where the slope climbs fastest), and the halo around
/// the contact out to [`HALO_RING`] of its radius.
pub const RINGS: usize = 6;
/// Rings inside the contact (the first [`CONTACT_RINGS`] × [`SECTORS`] sector means).
pub const CONTACT_RINGS: usize = RINGS - 1;
/// Each ring's outer edge, share of the contact radius (the halo's last).
pub const RING_EDGES: [f64; RINGS] = [0.35, 0.6, 0.8, 0.9, 1.0, 1.5];
/// The halo ring's outer edge, share of the contact radius.
pub const HALO_RING: f64 = RING_EDGES[RINGS - 1];

/// The presses' colour response and noise.
#[derive(Debug, Clone, PartialEq)]
pub struct PressStats {
    /// Mean (press − background) per channel, sector `k` of ring `r` at `r × SECTORS + k`
    /// (the halo ring last).
    pub sectors_rgb: Vec<[f64; 3]>,
    /// Mean (press − background) per channel over the contacts.
    pub mean_rgb: [f64; 3],
    /// Mean |press − background| per channel over the contacts.
    pub mean_abs_rgb: [f64; 3],
    /// RMS (press − background) per channel at least 2 radii + 8 px from the contact
    /// (every seventh pixel), grey levels.
    pub noise_rgb: [f64; 3],
}

impl PressStats {
    /// The sector means inside the contact (without the halo ring).
    pub fn contact_sectors(&self) -> &[[f64; 3]] {
        &self.sectors_rgb[..self.sectors_rgb.len().min(CONTACT_RINGS * SECTORS)]
    }

    /// Per channel: the first harmonic of the contact's sector means over the azimuth the surface
    /// normal tips towards (opposite the sector): (amplitude in grey levels, azimuth of the
    /// peak in degrees, 0–360). The azimuth is where that channel's light comes from.
    pub fn harmonic(&self) -> [(f64, f64); 3] {
        [0, 1, 2].map(|c| {
            let (mut a, mut b) = (0.0, 0.0);
            let inside = self.contact_sectors();
            for (i, s) in inside.iter().enumerate() {
                let tip = ((i % SECTORS) as f64 * 45.0 + 180.0).to_radians();
                a += s[c] * tip.cos();
                b += s[c] * tip.sin();
            }
            let n = inside.len().max(1) as f64;
            (
                2.0 * a.hypot(b) / n,
                b.atan2(a).to_degrees().rem_euclid(360.0),
            )
        })
    }
}

fn sector_of(dx: f64, dy: f64, r: f64, radius: f64) -> usize {
    let k = (dy.atan2(dx).to_degrees() / 45.0)
        .round()
        .rem_euclid(SECTORS as f64) as usize;
    let ring = RING_EDGES
        .iter()
        .position(|edge| r < edge * radius)
        .unwrap_or(RINGS - 1);
    ring * SECTORS + k % SECTORS
}

/// Sums per sector (rgb, count) of `diff` over the pixels inside `contact` and its halo
/// (every `stride`-th row and column).
fn accumulate(
    contact: &Contact,
    (w, h): (usize, usize),
    stride: usize,
    sums: &mut [([f64; 3], usize)],
    mut diff: impl FnMut(usize, usize, f64, f64) -> [f64; 3],
) {
    let radius = contact.radius_px;
    let a = HALO_RING * radius;
    let (x0, x1) = (
        (contact.center_x_px - a).floor().max(0.0) as usize,
        ((contact.center_x_px + a).ceil().max(0.0) as usize).min(w),
    );
    let (y0, y1) = (
        (contact.center_y_px - a).floor().max(0.0) as usize,
        ((contact.center_y_px + a).ceil().max(0.0) as usize).min(h),
    );
    for y in (y0..y1).step_by(stride.max(1)) {
        for x in (x0..x1).step_by(stride.max(1)) {
            let (dx, dy) = (
                x as f64 - contact.center_x_px,
                y as f64 - contact.center_y_px,
            );
            let r = dx.hypot(dy);
            if r >= a {
                continue;
            }
            let d = diff(x, y, dx, dy);
            let s = &mut sums[sector_of(dx, dy, r, radius)];
            s.0.iter_mut().zip(d).for_each(|(s, d)| *s += d);
            s.1 += 1;
        }
    }
}

/// [`PressStats`] of `presses` against `background`.
pub fn press_stats(background: Image<'_>, presses: &[(Contact, Image<'_>)]) -> PressStats {
    let (w, h) = (background.width_px, background.height_px);
    let mut sums = vec![([0.0; 3], 0usize); SECTORS * RINGS];
    let (mut abs, mut n_in) = ([0.0; 3], 0usize);
    let (mut sq, mut n_far) = ([0.0; 3], 0usize);
    for (contact, img) in presses {
        accumulate(contact, (w, h), 1, &mut sums, |x, y, dx, dy| {
            let d = [0, 1, 2].map(|c| img.at(x, y, c) - background.at(x, y, c));
            if dx.hypot(dy) < contact.radius_px {
                for c in 0..3 {
                    abs[c] += d[c].abs();
                }
                n_in += 1;
            }
            d
        });
        let far = 2.0 * contact.radius_px + 8.0;
        for p in (0..w * h).step_by(7) {
            let (x, y) = (p % w, p / w);
            if (x as f64 - contact.center_x_px).hypot(y as f64 - contact.center_y_px) < far {
                continue;
            }
            for (c, sq) in sq.iter_mut().enumerate() {
                let d = img.at(x, y, c) - background.at(x, y, c);
                *sq += d * d;
            }
            n_far += 1;
        }
    }
    let total: ([f64; 3], usize) = sums[..CONTACT_RINGS * SECTORS]
        .iter()
        .fold(([0.0; 3], 0), |(s, n), (v, k)| {
            ([s[0] + v[0], s[1] + v[1], s[2] + v[2]], n + k)
        });
    PressStats {
        sectors_rgb: sums
            .iter()
            .map(|(s, n)| s.map(|v| v / (*n).max(1) as f64))
            .collect(),
        mean_rgb: total.0.map(|v| v / total.1.max(1) as f64),
        mean_abs_rgb: abs.map(|v| v / n_in.max(1) as f64),
        noise_rgb: sq.map(|v| (v / n_far.max(1) as f64).sqrt()),
    }
}

/// Least-squares coefficients of [`background_basis`] per channel for `img` (every
/// `stride`-th row and column).
pub fn fit_background(img: Image<'_>, stride: usize) -> [[f64; BACKGROUND_TERMS]; 3] {
    let (w, h) = (img.width_px, img.height_px);
    let mut ata = [[0.0; BACKGROUND_TERMS]; BACKGROUND_TERMS];
    let mut atb = [[0.0; BACKGROUND_TERMS]; 3];
    for y in (0..h).step_by(stride.max(1)) {
        for x in (0..w).step_by(stride.max(1)) {
            let u = (x as f64 + 0.5) / w as f64 - 0.5;
            let v = (y as f64 + 0.5) / h as f64 - 0.5;
            let b = background_basis(u, v);
            let rgb = [0, 1, 2].map(|c| img.at(x, y, c));
            for (i, bi) in b.iter().enumerate() {
                for (a, bj) in ata[i].iter_mut().zip(&b) {
                    *a += bi * bj;
                }
                for (rhs, v) in atb.iter_mut().zip(rgb) {
                    rhs[i] += bi * v;
                }
            }
        }
    }
    atb.map(|rhs| solve(ata, rhs))
}

/// Solve `a x = b` by Gaussian elimination with partial pivoting (0 for a singular column).
fn solve(
    mut a: [[f64; BACKGROUND_TERMS]; BACKGROUND_TERMS],
    mut b: [f64; BACKGROUND_TERMS],
) -> [f64; BACKGROUND_TERMS] {
    let n = BACKGROUND_TERMS;
    for col in 0..n {
        let piv = (col..n)
            .max_by(|i, j| a[*i][col].abs().total_cmp(&a[*j][col].abs()))
            .unwrap_or(col);
        a.swap(col, piv);
        b.swap(col, piv);
        if a[col][col].abs() < 1e-12 {
            continue;
        }
        let pivot_row = a[col];
        for row in col + 1..n {
            let f = a[row][col] / pivot_row[col];
            for (v, p) in a[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *v -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0; BACKGROUND_TERMS];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| a[row][k] * x[k]).sum();
        x[row] = if a[row][row].abs() < 1e-12 {
            0.0
        } else {
            (b[row] - s) / a[row][row]
        };
    }
    x
}

/// How the fit renders the real presses: the ball, how much of each labelled contact the
/// ball really touches, and the gel's skirt around it ([`crate::gel`]), px.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressGeometry {
    /// Ball radius, px.
    pub ball_radius_px: f64,
    /// The ball's contact radius as a share of the labelled contact radius (the labels
    /// circle the visible imprint, which the skirt widens).
    pub contact_share: f64,
    /// The skirt's length ℓ, px (0: the gel stops at the rim).
    pub skirt_px: f64,
}

impl PressGeometry {
    /// The press of a labelled contact of radius `labelled_px`.
    pub fn press(&self, labelled_px: f64) -> BallOnGel {
        BallOnGel::new(
            self.ball_radius_px,
            self.contact_share * labelled_px,
            self.skirt_px,
        )
    }
}

/// The sector means (as [`PressStats::sectors_rgb`]) of noise-free renders with `params`
/// of each of `contacts` pressed as `geometry` says, every `stride`-th pixel; the gradient
/// is the press's, analytically.
pub fn model_sectors(
    params: &RealisticParams,
    size: (usize, usize),
    contacts: &[Contact],
    geometry: &PressGeometry,
    stride: usize,
) -> Vec<[f64; 3]> {
    let shader = RealisticShader::new(params, size.0, size.1, &UnitVariation::NEUTRAL);
    let mut sums = vec![([0.0; 3], 0usize); SECTORS * RINGS];
    for contact in contacts {
        let press = geometry.press(contact.radius_px);
        accumulate(contact, size, stride, &mut sums, |x, y, dx, dy| {
            let rho = dx.hypot(dy);
            let (_, slope) = press.at(rho);
            let (gx, gy) = if rho > 0.0 {
                (slope * dx / rho, slope * dy / rho)
            } else {
                (0.0, 0.0)
            };
            let lit = shader.shade(x, y, gx, gy);
            let flat = shader.shade(x, y, 0.0, 0.0);
            [0, 1, 2].map(|c| lit[c].clamp(0.0, 255.0) - flat[c].clamp(0.0, 255.0))
        });
    }
    sums.iter()
        .map(|(s, n)| s.map(|v| v / (*n).max(1) as f64))
        .collect()
}

/// The fitted press parameters and the geometry found with them.
#[derive(Debug, Clone, PartialEq)]
pub struct PressFit {
    /// The parameters (background and noise as given; `skirt_mm` left as given, the skirt
    /// is in `geometry`, px).
    pub params: RealisticParams,
    /// The presses' geometry.
    pub geometry: PressGeometry,
    /// The loss at the end: [`PressFit::rms`] plus, with a response target,
    /// [`RESPONSE_WEIGHT_GREY`] × the RMS of [`PressFit::response`] from it.
    pub loss: f64,
    /// RMS difference of all the sector means (halo included) from the target's, grey
    /// levels.
    pub rms: f64,
    /// The same over the contact's sectors only.
    pub contact_rms: f64,
    /// The fitted optics' response curve at the real contacts (compare it with the
    /// target's by [`ResponseCurve::rms_from`]).
    pub response: ResponseCurve,
    /// Coordinate-descent rounds run.
    pub rounds: usize,
}

/// What [`fit_presses`] matches: the real presses' sector means and, optionally, their
/// [`ResponseCurve`] (what a table trained on them reads).
#[derive(Debug, Clone, Copy)]
pub struct FitTarget<'a> {
    /// The real presses' colour statistics.
    pub sectors: &'a PressStats,
    /// The real presses' response curve, which the curve of the rendered pixels
    /// ([`crate::optics::response::model_pixels`]) is to match.
    pub response: Option<&'a ResponseCurve>,
}

/// Grey levels of sector-mean error that weigh as much as one unit of response-curve
/// error in [`fit_presses`]' loss: a table misreading slopes by 0.1 costs as much as the
/// colours missing by 10 levels (the sector means' own RMS, about 20 levels, is what the
/// model's shading cannot reproduce at all: the real gel's tint where it is pressed).
pub const RESPONSE_WEIGHT_GREY: f64 = 100.0;

/// Whether [`fit_presses`] fits the presses' geometry with the optics.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GeometryFit {
    /// Ball, contact share and skirt fitted with the optics (labels that circle an
    /// imprint of unknown ball).
    Fitted,
    /// Held as given (labels found for a known ball, as `calibrate label` does).
    Held,
}

/// The fitted values, in [`fit_presses`]'s order.
const FITTED: usize = 16;

fn fitted_values(p: &RealisticParams, g: &PressGeometry) -> [f64; FITTED] {
    [
        p.led_azimuth_deg[0],
        p.led_azimuth_deg[1],
        p.led_azimuth_deg[2],
        p.led_elevation_deg,
        p.ambient[0],
        p.ambient[1],
        p.ambient[2],
        p.specular,
        p.shininess,
        p.shadow_slope,
        p.crosstalk,
        p.gamma,
        g.ball_radius_px,
        p.wrap,
        g.contact_share,
        g.skirt_px,
    ]
}

fn with_values(start: &RealisticParams, v: &[f64; FITTED]) -> (RealisticParams, PressGeometry) {
    let mut p = *start;
    p.led_azimuth_deg = [v[0], v[1], v[2]];
    p.led_elevation_deg = v[3];
    p.ambient = [v[4], v[5], v[6]];
    p.specular = v[7];
    p.shininess = v[8];
    p.shadow_slope = v[9];
    p.crosstalk = v[10];
    p.gamma = v[11];
    p.wrap = v[13];
    let g = PressGeometry {
        ball_radius_px: v[12],
        contact_share: v[14],
        skirt_px: v[15],
    };
    (p, g)
}

/// RMS of the difference of two lists of sector means, grey levels.
pub fn sector_rms(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    let n = a.len().min(b.len());
    let se: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).powi(2)))
        .sum();
    (se / (3 * n).max(1) as f64).sqrt()
}

/// Fit the reflectance (and its wrap), shadowing, crosstalk, gamma and the presses'
/// geometry (ball, contact share, skirt) of `start` so that [`model_sectors`] matches
/// `target`'s sector means, halo included, at `contacts` (coordinate descent, halving each
/// step when neither direction helps). With [`GeometryFit::Held`] the geometry stays as
/// given (the presses' labels were found for that ball).
pub fn fit_presses(
    start: &RealisticParams,
    (geometry, geometry_fit): (&PressGeometry, GeometryFit),
    target: FitTarget<'_>,
    size: (usize, usize),
    contacts: &[Contact],
    max_rounds: usize,
) -> PressFit {
    let largest = contacts.iter().map(|c| c.radius_px).fold(1.0, f64::max);
    // (step, lower, upper) per parameter; the order of `fitted_values`.
    let mut steps = [
        (10.0, -720.0, 720.0),
        (10.0, -720.0, 720.0),
        (10.0, -720.0, 720.0),
        (5.0, 3.0, 80.0),
        (0.1, 0.01, 5.0),
        (0.1, 0.01, 5.0),
        (0.1, 0.01, 5.0),
        (0.1, 0.0, 3.0),
        (5.0, 1.0, 100.0),
        (0.2, 0.1, 10.0),
        (0.03, 0.0, 0.3),
        (0.2, 1.0, 3.0),
        (10.0, 1.0, 400.0),
        (0.1, 0.0, 1.0),
        (0.05, 0.2, 1.0),
        (4.0, 0.0, 80.0),
    ];
    if geometry_fit == GeometryFit::Held {
        for i in [12, 14, 15] {
            steps[i].0 = 0.0;
        }
    }
    // The ball is larger than every contact it makes.
    let clamp_ball = |v: &mut [f64; FITTED]| v[12] = v[12].max(v[14] * largest + 1.0);
    let loss = |v: &[f64; FITTED]| {
        let (p, g) = with_values(start, v);
        let m = model_sectors(&p, size, contacts, &g, 2);
        let sectors = sector_rms(&m, &target.sectors.sectors_rgb);
        sectors
            + target.response.map_or(0.0, |real| {
                let model = ResponseCurve::of(&model_pixels(&p, size, contacts, &g, 2));
                RESPONSE_WEIGHT_GREY * model.rms_from(real)
            })
    };
    let mut v = fitted_values(start, geometry);
    clamp_ball(&mut v);
    let mut best = loss(&v);
    let mut rounds = 0;
    while rounds < max_rounds && steps.iter().any(|(s, lo, hi)| *s > (hi - lo) * 1e-3) {
        rounds += 1;
        for i in 0..v.len() {
            let (step, lo, hi) = steps[i];
            let mut moved = false;
            for dir in [1.0, -1.0] {
                let mut t = v;
                t[i] = (v[i] + dir * step).clamp(lo, hi);
                clamp_ball(&mut t);
                let l = loss(&t);
                if l < best {
                    (v, best, moved) = (t, l, true);
                    break;
                }
            }
            if !moved {
                steps[i].0 = step / 2.0;
            }
        }
    }
    let (mut params, geometry) = with_values(start, &v);
    params.led_azimuth_deg = params.led_azimuth_deg.map(|a| a.rem_euclid(360.0));
    let m = model_sectors(&params, size, contacts, &geometry, 2);
    let inside = CONTACT_RINGS * SECTORS;
    PressFit {
        response: ResponseCurve::of(&model_pixels(&params, size, contacts, &geometry, 2)),
        params,
        geometry,
        loss: best,
        rms: sector_rms(&m, &target.sectors.sectors_rgb),
        contact_rms: sector_rms(&m[..inside], &target.sectors.sectors_rgb[..inside]),
        rounds,
    }
}

#[cfg(test)]
mod tests {
    use super::super::realistic::MINI;
    use super::*;

    #[test]
    fn the_background_fit_recovers_a_polynomial() {
        let (w, h) = (64, 48);
        let mut want = MINI;
        want.background[0] = [100.0, 20.0, -10.0, -80.0, 5.0, -60.0, 3.0, 0.0, -2.0, 1.0];
        let rgb: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .flat_map(|(x, y)| {
                super::super::realistic::background_rgb(&want, x, y, w, h)
                    .map(|v| v.round().clamp(0.0, 255.0) as u8)
            })
            .collect();
        let img = Image {
            width_px: w,
            height_px: h,
            rgb: &rgb,
        };
        let got = fit_background(img, 1);
        assert!((got[0][0] - 100.0).abs() < 0.5, "{:?}", got[0]);
        assert!((got[0][3] + 80.0).abs() < 3.0, "{:?}", got[0]);
        let stats = background_stats(img);
        assert!(stats.falloff_rgb()[0] < 0.9, "{stats:?}");
    }

    #[test]
    fn the_harmonic_points_at_the_light() {
        // Red brightens where the normal tips towards +y (sector 6, at −90°, is above the
        // centre; its normal tips to +90°).
        let mut sectors = vec![[0.0; 3]; SECTORS * RINGS];
        for (i, s) in sectors.iter_mut().enumerate() {
            let tip = ((i % SECTORS) as f64 * 45.0 + 180.0).to_radians();
            s[0] = 10.0 * (tip - 90f64.to_radians()).cos();
        }
        let stats = PressStats {
            sectors_rgb: sectors,
            mean_rgb: [0.0; 3],
            mean_abs_rgb: [0.0; 3],
            noise_rgb: [0.0; 3],
        };
        let [(amp, az), _, _] = stats.harmonic();
        assert!(
            (amp - 10.0).abs() < 1e-9 && (az - 90.0).abs() < 1e-9,
            "{amp} {az}"
        );
    }
}
