//! The gel's shear from its marker dots: each reference dot followed from frame to frame,
//! and, under a contact, the mean shift, the stick ratio that the shifts' pattern shows,
//! and the slip state (docs/slip.md).
//!
//! A dot is matched to the frame's dot nearest where it was last seen (its reference place
//! plus its last shift), within half the grid's pitch (the median distance between
//! neighbouring reference dots). Its shift is from its reference place: the reference is
//! the calibration's and is never refreshed by drift tracking, so shear is not absorbed.
//!
//! Under a contact of radius a (a disc of the contact's area) centred on the contact's
//! centroid (the depth map's: the stick zone is concentric with the contact), the dots
//! within 2a give the shift's pattern. Cattaneo–Mindlin's shift along the load,
//! U/2 · (H(r/a) − s² H(r/(sa))) ([`cattaneo_shift`]), is fitted to their shifts along the
//! moved dots' direction over the stick ratio s (a grid of [`FIT_STEPS`] values; U in
//! closed form for each) and the contact's radius (around the depth map's, which reads a
//! small indenter's contact wide). The estimate is the stickiest fit that the dots cannot
//! tell from the best, given their own noise (measured on the no-contact frames of the
//! calibration). A contact whose field peaks under [`SHEAR_FLOOR_SIGMAS`] of that noise
//! carries no load that the dots can tell: stick ratio 1.

pub use gelgrip_controller::fusion::SlipState;
#[cfg(test)]
use gelgrip_controller::markers::cattaneo_shift;
use gelgrip_controller::markers::{cattaneo_shift_of, hertz_profile};

/// Without a measured noise ([`DotTracker::learn_noise`]), a field whose peak shift is
/// under this, px, is the dots' own noise (their centres are found to about a twentieth of
/// a pixel): no shear.
pub const SHEAR_FLOOR_PX: f64 = 0.25;
/// With a measured noise σ (px, per axis), a field whose peak shift is under this many σ
/// is noise: no shear.
pub const SHEAR_FLOOR_SIGMAS: f64 = 8.0;
/// A stick ratio is as good as the best fit's while its residual is within this many σ²
/// of the best's (3σ: the dots cannot tell them apart); the estimate is the stickiest such.
pub const FIT_CONFIDENCE_SIGMAS2: f64 = 9.0;
/// A contact slips incipiently below this estimated stick ratio.
pub const INCIPIENT_STICK_RATIO: f64 = 0.9;
/// A contact slides (gross slip) below this estimated stick ratio.
pub const GROSS_STICK_RATIO: f64 = 0.25;
/// Stick ratios tried by the fit (0, 1/FIT_STEPS, … below 1).
pub const FIT_STEPS: usize = 50;
/// Dots out to this many contact radii (the depth map's) enter the fit.
const FIT_REACH: f64 = 2.0;

/// One contact's shear, as its marker dots show it.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ShearEstimate {
    /// Mean shift of the dots inside the contact, `[x, y]` mm (image axes).
    pub shear_mm: [f64; 2],
    /// Estimated stick ratio c/a.
    pub stick_ratio: f64,
    /// What that makes of the contact.
    pub state: SlipState,
    /// Dots inside the contact.
    pub dots_inside: usize,
}

impl ShearEstimate {
    /// As the controller reads it.
    pub fn slip(&self) -> gelgrip_controller::fusion::SensorSlip {
        gelgrip_controller::fusion::SensorSlip {
            shear_mm: self.shear_mm,
            stick_ratio: self.stick_ratio,
            state: self.state,
        }
    }

    /// The mean shift's size, mm.
    pub fn magnitude_mm(&self) -> f64 {
        self.shear_mm[0].hypot(self.shear_mm[1])
    }

    /// The mean shift's direction, degrees from the image's x axis towards its y axis.
    pub fn direction_deg(&self) -> f64 {
        self.shear_mm[1].atan2(self.shear_mm[0]).to_degrees()
    }
}

/// The reference's dots and each one's shift in the last frame.
#[derive(Debug, Clone, PartialEq)]
pub struct DotTracker {
    reference: Vec<(f64, f64)>,
    shift: Vec<Option<(f64, f64)>>,
    pitch_px: f64,
    /// The dots' noise as learnt on frames with nothing touching: the sum of their squared
    /// shifts per axis, and how many axes were summed.
    noise: (f64, usize),
    /// Working space: the frame's dots by grid cell.
    cells: DotCells,
}

impl DotTracker {
    /// A tracker of the reference's dot centres, px.
    pub fn new(reference: Vec<(f64, f64)>) -> Self {
        let pitch_px = median_neighbour_distance(&reference).unwrap_or(1.0);
        Self {
            shift: vec![None; reference.len()],
            reference,
            pitch_px,
            noise: (0.0, 0),
            cells: DotCells::default(),
        }
    }

    /// The reference's dots.
    pub fn len(&self) -> usize {
        self.reference.len()
    }

    /// Whether it has none.
    pub fn is_empty(&self) -> bool {
        self.reference.is_empty()
    }

    /// The grid's pitch, px.
    pub fn pitch_px(&self) -> f64 {
        self.pitch_px
    }

    /// Each reference dot with its shift in the last frame (`None`: not found).
    pub fn shifts(&self) -> impl Iterator<Item = ((f64, f64), Option<(f64, f64)>)> + '_ {
        self.reference
            .iter()
            .copied()
            .zip(self.shift.iter().copied())
    }

    /// Count the last frame, one with nothing touching, towards the dots' noise: every
    /// found dot's shift from its reference place (the reference is those frames' mean).
    pub fn learn_noise(&mut self) {
        for (dx, dy) in self.shift.iter().flatten() {
            self.noise.0 += dx * dx + dy * dy;
            self.noise.1 += 2;
        }
    }

    /// The dots' noise per axis, px (`None` until frames were learnt).
    pub fn noise_px(&self) -> Option<f64> {
        let (sum, n) = self.noise;
        (n > 1)
            .then(|| (sum / n as f64).sqrt())
            .filter(|v| v.is_finite())
    }

    /// Match the frame's dots (centres, px) to the reference's.
    pub fn track(&mut self, frame: &[super::Dot]) {
        let cell = self.pitch_px.max(1.0);
        self.cells.fill(&self.reference, cell, frame);
        let reach = 0.5 * self.pitch_px;
        for (r, shift) in self.reference.iter().zip(self.shift.iter_mut()) {
            let (dx, dy) = shift.unwrap_or((0.0, 0.0));
            let at = (r.0 + dx, r.1 + dy);
            let nearest = self
                .cells
                .around(at)
                .map(|p| (p, (p.0 - at.0).hypot(p.1 - at.1)))
                .filter(|(_, d)| *d <= reach)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            *shift = nearest.map(|(p, _)| (p.0 - r.0, p.1 - r.1));
        }
    }

    /// The shear under a contact centred at `centre_px` of radius `radius_px` (the depth
    /// map's), at `mm_per_px`; `None` without dots moved near it.
    pub fn estimate(
        &self,
        centre_px: (f64, f64),
        radius_px: f64,
        mm_per_px: f64,
    ) -> Option<ShearEstimate> {
        if !(radius_px > 0.0 && radius_px.is_finite() && mm_per_px > 0.0) {
            return None;
        }
        // The dots near the contact and their shifts.
        let near: Vec<MovedDot> = self
            .shifts()
            .filter_map(|(r, s)| {
                let rho = (r.0 - centre_px.0).hypot(r.1 - centre_px.1) / radius_px;
                s.filter(|_| rho <= FIT_REACH).map(|s| (r, s))
            })
            .collect();
        let field = ShiftField::of(&near)?;
        let distance = |r: (f64, f64)| (r.0 - centre_px.0).hypot(r.1 - centre_px.1);
        let inside: Vec<(f64, f64)> = near
            .iter()
            .filter(|(r, _)| distance(*r) <= radius_px)
            .map(|n| n.1)
            .collect();
        let n = inside.len().max(1) as f64;
        let mean = (
            inside.iter().map(|s| s.0).sum::<f64>() / n,
            inside.iter().map(|s| s.1).sum::<f64>() / n,
        );
        let noise = self.noise_px();
        let floor = noise.map_or(SHEAR_FLOOR_PX, |s| SHEAR_FLOOR_SIGMAS * s);
        let stick_ratio = if field.peak_px < floor {
            1.0
        } else {
            fit_around(&near, &field, centre_px, radius_px, noise)
        };
        Some(ShearEstimate {
            shear_mm: [mean.0 * mm_per_px, mean.1 * mm_per_px],
            stick_ratio,
            state: state_of(stick_ratio),
            dots_inside: inside.len(),
        })
    }
}

/// The stick ratio of the pattern of the `near` dots' shifts along the `field`, fitted
/// around `centre_px` (the depth map's centroid) and then again around the centre that the
/// first fit's pattern points to: the depth map's centroid is the contact's to a few px,
/// and at the contact's rim, where the pattern is steepest, a few px tell.
fn fit_around(
    near: &[MovedDot],
    field: &ShiftField,
    centre_px: (f64, f64),
    radius_px: f64,
    noise: Option<f64>,
) -> f64 {
    let along_from = |c: (f64, f64)| -> Vec<(f64, f64)> {
        near.iter()
            .map(|(r, s)| ((r.0 - c.0).hypot(r.1 - c.1), field.along(*s)))
            .collect()
    };
    let first = best_of(&fit_grid(&along_from(centre_px), radius_px, false));
    let offset = first.and_then(|best| centre_offset(near, field, centre_px, &best));
    let (ex, ey) = offset.unwrap_or((0.0, 0.0));
    let moved = (centre_px.0 + ex, centre_px.1 + ey);
    fit_stick_ratio(&along_from(moved), radius_px, noise)
}

/// How far the pattern's centre lies from `centre_px`, px, to first order: the shift
/// along the field, less the `best` fit's pattern, regressed on the pattern's change as
/// its centre moves. `None` when the dots do not tell (too few, or all on a line), and at
/// most [`CENTRE_REACH`] of the fit's radius.
fn centre_offset(
    near: &[MovedDot],
    field: &ShiftField,
    centre_px: (f64, f64),
    best: &Fit,
) -> Option<(f64, f64)> {
    const STEP: f64 = 0.01;
    let (mut gxx, mut gxy, mut gyy, mut bx, mut by) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (r, s) in near {
        let (dx, dy) = (r.0 - centre_px.0, r.1 - centre_px.1);
        let d = dx.hypot(dy);
        if d <= 0.0 {
            continue;
        }
        let rho = d / best.radius_px;
        let pattern = |rho: f64| best.scale * tabled_shift(rho, best.stick_ratio);
        let slope = (pattern(rho + STEP) - pattern((rho - STEP).max(0.0))) / (2.0 * STEP);
        // Moving the centre by e moves this dot's ρ by −(e · r̂)/radius.
        let (gx, gy) = (
            -slope * dx / d / best.radius_px,
            -slope * dy / d / best.radius_px,
        );
        let residual = field.along(*s) - pattern(rho);
        (gxx, gxy, gyy) = (gxx + gx * gx, gxy + gx * gy, gyy + gy * gy);
        (bx, by) = (bx + gx * residual, by + gy * residual);
    }
    let det = gxx * gyy - gxy * gxy;
    let tells = det.is_finite() && det > 1e-12 * (gxx * gyy).max(1e-300);
    if !tells {
        return None;
    }
    let (ex, ey) = ((gyy * bx - gxy * by) / det, (gxx * by - gxy * bx) / det);
    let size = ex.hypot(ey);
    let most = CENTRE_REACH * best.radius_px;
    let keep = if size > most { most / size } else { 1.0 };
    (size.is_finite() && size > 0.0).then_some((ex * keep, ey * keep))
}

/// The pattern's centre is looked for at most this share of the contact's radius from the
/// depth map's centroid.
const CENTRE_REACH: f64 = 0.15;

/// A contact's slip state holds once this many frames in a row show it.
pub const CONFIRM_FRAMES: usize = 3;

/// A contact's estimated stick ratios over its last frames: its state is that of the
/// stickiest of the last [`CONFIRM_FRAMES`] (a frame without a reading counts as sticking).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Confirmation {
    /// The readings of the frames before, each with its frame.
    recent: Vec<(u64, f64)>,
}

impl Confirmation {
    /// Count frame `frame`'s reading `stick_ratio` (`None`: none) and return the stick
    /// ratio its state is read from.
    pub fn confirm(&mut self, frame: u64, stick_ratio: Option<f64>) -> f64 {
        let before = (1..CONFIRM_FRAMES as u64)
            .map(|k| {
                self.recent
                    .iter()
                    .find(|(f, _)| f + k == frame)
                    .map_or(1.0, |(_, s)| *s)
            })
            .fold(0.0, f64::max);
        // Keep what the next frame needs: this one and the CONFIRM_FRAMES − 2 before.
        self.recent
            .retain(|(f, _)| f + CONFIRM_FRAMES as u64 > frame + 1);
        match stick_ratio {
            Some(s) => {
                self.recent.push((frame, s));
                s.max(before)
            }
            None => 1.0,
        }
    }
}

/// A frame's dots binned in square cells of the grid's pitch, over the reference's extent
/// and a cell around it (a dot farther out is matched to no reference dot: they are looked
/// for within half the pitch).
#[derive(Debug, Clone, Default, PartialEq)]
struct DotCells {
    cell_px: f64,
    /// Cells across and down; cell (0, 0) starts a cell left of and above the reference.
    cols: usize,
    rows: usize,
    origin: (f64, f64),
    dots: Vec<Vec<(f64, f64)>>,
}

impl DotCells {
    /// Bin `frame`'s dots in cells of `cell_px` around `reference`.
    fn fill(&mut self, reference: &[(f64, f64)], cell_px: f64, frame: &[super::Dot]) {
        let (mut lo, mut hi) = (
            (f64::INFINITY, f64::INFINITY),
            (f64::NEG_INFINITY, f64::NEG_INFINITY),
        );
        for &(x, y) in reference {
            (lo, hi) = ((lo.0.min(x), lo.1.min(y)), (hi.0.max(x), hi.1.max(y)));
        }
        if !(lo.0.is_finite() && hi.0.is_finite()) {
            (lo, hi) = ((0.0, 0.0), (0.0, 0.0));
        }
        self.cell_px = cell_px;
        self.origin = (lo.0 - cell_px, lo.1 - cell_px);
        self.cols = ((hi.0 - lo.0) / cell_px) as usize + 3;
        self.rows = ((hi.1 - lo.1) / cell_px) as usize + 3;
        self.dots.iter_mut().for_each(Vec::clear);
        self.dots.resize(self.cols * self.rows, Vec::new());
        for d in frame {
            if let Some(k) = self.index(self.cell_of(d.centre_px)) {
                self.dots[k].push(d.centre_px);
            }
        }
    }

    /// The cell of point `(x, y)`, as (column, row) (negative or beyond: outside).
    fn cell_of(&self, (x, y): (f64, f64)) -> (i64, i64) {
        (
            ((x - self.origin.0) / self.cell_px).floor() as i64,
            ((y - self.origin.1) / self.cell_px).floor() as i64,
        )
    }

    /// The index of cell `(c, r)`, when it is one.
    fn index(&self, (c, r): (i64, i64)) -> Option<usize> {
        let (c, r) = (usize::try_from(c).ok()?, usize::try_from(r).ok()?);
        (c < self.cols && r < self.rows).then(|| r * self.cols + c)
    }

    /// The dots in the 3 × 3 cells around `at`.
    fn around(&self, at: (f64, f64)) -> impl Iterator<Item = &(f64, f64)> {
        let (c, r) = self.cell_of(at);
        (r - 1..=r + 1)
            .flat_map(move |y| (c - 1..=c + 1).map(move |x| (x, y)))
            .filter_map(|k| self.index(k))
            .flat_map(|k| self.dots[k].iter())
    }
}

/// What a stick ratio makes of a contact.
pub fn state_of(stick_ratio: f64) -> SlipState {
    if stick_ratio < GROSS_STICK_RATIO {
        SlipState::Gross
    } else if stick_ratio < INCIPIENT_STICK_RATIO {
        SlipState::Incipient
    } else {
        SlipState::None
    }
}

/// The shift field's peak is its this-many-th largest shift (0-based), so that a few dots
/// mis-found do not make a shear.
const PEAK_RANK: usize = 4;

/// A dot's place at rest and its shift, px.
type MovedDot = ((f64, f64), (f64, f64));

/// Where the dots moved: the shift's direction (of the dots that moved at least half as
/// far as the most) and its peak.
#[derive(Debug, Clone, Copy)]
struct ShiftField {
    direction: (f64, f64),
    peak_px: f64,
}

impl ShiftField {
    /// The field of `dots` (place at rest, shift); `None` without any.
    fn of(dots: &[MovedDot]) -> Option<Self> {
        let size = |s: &(f64, f64)| s.0.hypot(s.1);
        // The peak: the [`PEAK_RANK`]th largest shift (a dot or two mis-found, at a
        // contact's steep rim, must not make a shear).
        let mut sizes: Vec<f64> = dots.iter().map(|(_, s)| size(s)).collect();
        sizes.sort_by(|a, b| b.total_cmp(a));
        let peak_px = sizes
            .get(PEAK_RANK.min(sizes.len().saturating_sub(1)))
            .copied()?;
        if !peak_px.is_finite() {
            return None;
        }
        let (dx, dy) = dots
            .iter()
            .filter(|(_, s)| size(s) >= 0.5 * peak_px)
            .fold((0.0, 0.0), |acc, (_, s)| (acc.0 + s.0, acc.1 + s.1));
        let norm = dx.hypot(dy);
        let direction = if norm > 0.0 {
            (dx / norm, dy / norm)
        } else {
            (1.0, 0.0)
        };
        Some(Self { direction, peak_px })
    }

    /// A shift's part along the direction, px.
    fn along(&self, s: (f64, f64)) -> f64 {
        s.0 * self.direction.0 + s.1 * self.direction.1
    }
}

/// The stick ratio of a Cattaneo–Mindlin shift pattern that fits `along` (distance from the
/// centre px, shift along the load px) in least squares, its scale free and the contact's
/// radius free (over [`RADIUS_SPAN`] of `radius_px`, the depth map's): of the fits within
/// [`FIT_TOLERANCE`] of the best, the one
/// that sticks most (the dots cannot tell them apart; a detector says slip only where
/// they can). With the dots' measured noise σ, px, "within" is within
/// [`FIT_CONFIDENCE_SIGMAS2`] σ² of the best or [`FIT_TOLERANCE`] of it, whichever is
/// wider.
fn fit_stick_ratio(along: &[(f64, f64)], radius_px: f64, noise_px: Option<f64>) -> f64 {
    let fits = fit_grid(along, radius_px, true);
    let best = best_of(&fits).map_or(f64::INFINITY, |f| f.residual);
    // The dots' noise here: the learnt one, or what the best fit leaves (dots under a
    // contact are found less surely than on the bare gel), whichever is larger.
    let left = best / along.len().saturating_sub(FIT_PARAMETERS).max(1) as f64;
    let within = noise_px.map_or(FIT_TOLERANCE * best, |s| {
        (best + FIT_CONFIDENCE_SIGMAS2 * (s * s).max(left)).max(FIT_TOLERANCE * best)
    });
    let stick = fits
        .iter()
        .filter(|f| f.residual <= within)
        .map(|f| f.stick_ratio)
        .fold(f64::NAN, f64::max);
    if stick.is_finite() { stick } else { 1.0 }
}

/// The fits tried: [`RADII`] radii over [`RADIUS_SPAN`] of `radius_px` at every
/// [`COARSE_EVERY`]th stick ratio, then, when `fine`, [`FINE_RADII`] radii around the best
/// of those at every stick ratio.
fn fit_grid(along: &[(f64, f64)], radius_px: f64, fine: bool) -> Vec<Fit> {
    let sticks: Vec<f64> = (0..=FIT_STEPS)
        .map(|k| (k as f64 / FIT_STEPS as f64).min(MAX_FIT_STICK))
        .collect();
    let coarse_sticks: Vec<f64> = sticks
        .iter()
        .enumerate()
        .filter(|(k, _)| k % COARSE_EVERY == 0 || *k == FIT_STEPS)
        .map(|(_, s)| *s)
        .collect();
    let extent = radius_px.max(1.0);
    let step = extent * (RADIUS_SPAN.1 - RADIUS_SPAN.0) / (RADII - 1) as f64;
    let mut fits = Vec::with_capacity(RADII * coarse_sticks.len() + FINE_RADII * sticks.len());
    for j in 0..RADII {
        fits_at(
            along,
            extent * RADIUS_SPAN.0 + step * j as f64,
            &coarse_sticks,
            &mut fits,
        );
    }
    if fine {
        let around = best_of(&fits).map_or(extent, |f| f.radius_px);
        for j in 0..FINE_RADII {
            let r = around - step + 2.0 * step * j as f64 / (FINE_RADII - 1) as f64;
            if r > 0.0 {
                fits_at(along, r, &sticks, &mut fits);
            }
        }
    }
    fits
}

/// The fit of least residual.
fn best_of(fits: &[Fit]) -> Option<Fit> {
    fits.iter()
        .min_by(|a, b| a.residual.total_cmp(&b.residual))
        .copied()
}

/// One Cattaneo–Mindlin pattern fitted to the dots.
#[derive(Debug, Clone, Copy)]
struct Fit {
    /// The sum of the squared differences, px².
    residual: f64,
    stick_ratio: f64,
    radius_px: f64,
    /// The pattern's scale (U/2, px).
    scale: f64,
}

/// The fit at contact radius `radius` px of each stick ratio of `sticks`, into `fits`.
/// One pass over the dots per stick ratio: the scale in closed form, and the residual as
/// Σu² − (Σuf)²/Σf².
fn fits_at(along: &[(f64, f64)], radius: f64, sticks: &[f64], fits: &mut Vec<Fit>) {
    let uu: f64 = along.iter().map(|(_, u)| u * u).sum();
    let whole: Vec<f64> = along
        .iter()
        .map(|(r, _)| tabled_profile(r / radius))
        .collect();
    for &s in sticks {
        let (mut uf, mut ff) = (0.0, 0.0);
        for ((r, u), h) in along.iter().zip(&whole) {
            let stick = if s > 0.0 {
                s * s * tabled_profile(r / (radius * s))
            } else {
                0.0
            };
            let f = (h - stick).max(0.0);
            uf += u * f;
            ff += f * f;
        }
        if !(ff > 0.0 && ff.is_finite() && uf.is_finite()) {
            continue;
        }
        fits.push(Fit {
            residual: (uu - uf * uf / ff).max(0.0),
            stick_ratio: s,
            radius_px: radius,
            scale: uf / ff,
        });
    }
}

/// The contact radii tried by the fit, as shares of the depth map's, and how many (a small
/// ball's depth map reaches past its contact, into the gel sagging around it: 1.3× for a
/// 6 mm ball 1 mm deep).
const RADIUS_SPAN: (f64, f64) = (0.6, 1.25);
const RADII: usize = 9;
/// The first pass tries every this-many-th stick ratio.
const COARSE_EVERY: usize = 6;
/// The second pass's radii, around the first's best.
const FINE_RADII: usize = 9;
/// What a fit is free in: the pattern's scale, the stick ratio and the contact's radius.
const FIT_PARAMETERS: usize = 3;
/// Fits whose residual is within this factor of the best are as good.
const FIT_TOLERANCE: f64 = 1.1;
/// The stickiest pattern tried (at 1 nothing moves).
const MAX_FIT_STICK: f64 = 0.98;

/// [`hertz_profile`] tabulated every 1/[`TABLE_PER_UNIT`] up to [`TABLE_REACH`] (linear
/// between entries: within 1e-3 of it, at ρ just past 1 where its curvature is infinite),
/// its 8/(3πρ) tail beyond.
fn tabled_profile(rho: f64) -> f64 {
    static TABLE: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        (0..=TABLE_REACH * TABLE_PER_UNIT)
            .map(|k| hertz_profile(k as f64 / TABLE_PER_UNIT as f64))
            .collect()
    });
    let rho = rho.abs();
    if !rho.is_finite() {
        return 0.0;
    }
    let at = rho * TABLE_PER_UNIT as f64;
    let k = at as usize;
    match (table.get(k), table.get(k + 1)) {
        (Some(a), Some(b)) => a + (b - a) * (at - k as f64),
        _ => 8.0 / (3.0 * std::f64::consts::PI * rho),
    }
}

/// [`cattaneo_shift`] through [`tabled_profile`].
fn tabled_shift(rho: f64, stick_ratio: f64) -> f64 {
    cattaneo_shift_of(tabled_profile, rho, stick_ratio)
}

/// The profile's table: entries per unit of ρ, and how far it reaches.
const TABLE_PER_UNIT: usize = 64;
const TABLE_REACH: usize = 64;

/// The median over `points` of the distance to the nearest other point.
fn median_neighbour_distance(points: &[(f64, f64)]) -> Option<f64> {
    let mut nearest: Vec<f64> = points
        .iter()
        .enumerate()
        .map(|(i, a)| {
            points
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, b)| (a.0 - b.0).hypot(a.1 - b.1))
                .fold(f64::INFINITY, f64::min)
        })
        .filter(|d| d.is_finite())
        .collect();
    nearest.sort_by(f64::total_cmp);
    nearest.get(nearest.len() / 2).copied()
}

#[cfg(test)]
mod tests {
    use super::super::Dot;
    use super::*;

    /// A 9 × 9 grid of dots 16 px apart around (80, 80), shifted by the Cattaneo pattern of
    /// a contact of radius 40 px and stick ratio `s` (peak `u` px along x).
    fn sheared(s: f64, u: f64) -> (DotTracker, Vec<Dot>) {
        sheared_at((80.0, 80.0), s, u)
    }

    /// [`sheared`] with the contact centred at `centre`.
    fn sheared_at(centre: (f64, f64), s: f64, u: f64) -> (DotTracker, Vec<Dot>) {
        let reference: Vec<(f64, f64)> = (0..9)
            .flat_map(|j| (0..9).map(move |i| (16.0 + 16.0 * i as f64, 16.0 + 16.0 * j as f64)))
            .collect();
        let frame = reference
            .iter()
            .map(|(x, y)| {
                let rho = (x - centre.0).hypot(y - centre.1) / 40.0;
                Dot {
                    area_px: 20,
                    centre_px: (x + u * cattaneo_shift(rho, s) / cattaneo_shift(0.0, s), *y),
                }
            })
            .collect();
        (DotTracker::new(reference), frame)
    }

    #[test]
    fn the_stick_ratio_and_state_come_back_from_the_dots_shifts() {
        for (s, state) in [
            (0.95, SlipState::None),
            (0.6, SlipState::Incipient),
            (0.0, SlipState::Gross),
        ] {
            let (mut tracker, frame) = sheared(s, 4.0);
            assert_eq!(tracker.pitch_px(), 16.0);
            tracker.track(&frame);
            let e = tracker
                .estimate((80.0, 80.0), 40.0, 0.05)
                .expect("dots inside");
            assert!((e.stick_ratio - s).abs() <= 0.17, "{s}: {e:?}");
            assert_eq!(e.state, state, "{s}: {e:?}");
            assert!(e.shear_mm[0] > 0.0 && e.shear_mm[1].abs() < 1e-9);
            assert!(e.direction_deg().abs() < 1e-6);
        }
        // No shift: stick ratio 1; no dots under a contact elsewhere: nothing.
        let (mut tracker, frame) = sheared(0.5, 0.0);
        tracker.track(&frame);
        let e = tracker
            .estimate((80.0, 80.0), 40.0, 0.05)
            .expect("dots inside");
        assert_eq!(
            (e.stick_ratio, e.state, e.magnitude_mm()),
            (1.0, SlipState::None, 0.0)
        );
        assert_eq!(tracker.estimate((500.0, 500.0), 10.0, 0.05), None);
        assert_eq!(tracker.estimate((80.0, 80.0), f64::NAN, 0.05), None);
    }

    #[test]
    fn the_pattern_is_fitted_where_it_is_centred_not_where_the_depth_map_puts_it() {
        // The depth map's centroid 7 px (a sixth of the radius) off the pattern's centre.
        let (mut tracker, frame) = sheared_at((86.0, 76.0), 0.95, 4.0);
        tracker.track(&frame);
        let e = tracker
            .estimate((80.0, 80.0), 40.0, 0.05)
            .expect("dots inside");
        assert!((e.stick_ratio - 0.95).abs() <= 0.05, "{e:?}");
        assert_eq!(e.state, SlipState::None, "{e:?}");
        // Fitted around the depth map's centroid alone, the same dots read 0.08 less stick:
        // slip, at the threshold.
        let along: Vec<(f64, f64)> = tracker
            .shifts()
            .filter_map(|(r, s)| Some(((r.0 - 80.0).hypot(r.1 - 80.0), s?.0)))
            .filter(|(d, _)| *d <= FIT_REACH * 40.0)
            .collect();
        let unmoved = fit_stick_ratio(&along, 40.0, None);
        assert!(
            unmoved <= INCIPIENT_STICK_RATIO && unmoved <= e.stick_ratio - 0.06,
            "{unmoved}"
        );
    }

    #[test]
    fn a_state_holds_once_three_frames_in_a_row_show_it() {
        let mut c = Confirmation::default();
        // Two frames of slip, then sticking: never confirmed.
        assert_eq!(c.confirm(1, Some(0.5)), 1.0);
        assert_eq!(c.confirm(2, Some(0.6)), 1.0);
        assert_eq!(c.confirm(3, Some(0.98)), 0.98);
        // Three in a row: the stickiest of them.
        assert_eq!(c.confirm(4, Some(0.7)), 0.98);
        assert_eq!(c.confirm(5, Some(0.6)), 0.98);
        assert_eq!(c.confirm(6, Some(0.5)), 0.7);
        // A frame without a reading breaks the run.
        assert_eq!(c.confirm(7, None), 1.0);
        assert_eq!(c.confirm(8, Some(0.4)), 1.0);
        assert_eq!(c.confirm(9, Some(0.4)), 1.0);
        assert_eq!(c.confirm(10, Some(0.4)), 0.4);
        // A gap between frames too.
        assert_eq!(c.confirm(12, Some(0.4)), 1.0);
        assert!(c.recent.len() < CONFIRM_FRAMES);
    }

    #[test]
    fn the_dots_noise_is_learnt_and_a_shift_within_it_is_no_shear() {
        let (mut tracker, frame) = sheared(0.5, 0.0);
        assert_eq!(tracker.noise_px(), None);
        // Quiet frames: every dot found 0.05 px off its place, along x then along y.
        for k in 0..4 {
            let jitter: Vec<Dot> = frame
                .iter()
                .map(|d| {
                    let (x, y) = d.centre_px;
                    let off = if k % 2 == 0 {
                        (0.05, 0.0)
                    } else {
                        (0.0, -0.05)
                    };
                    Dot {
                        area_px: 20,
                        centre_px: (x + off.0, y + off.1),
                    }
                })
                .collect();
            tracker.track(&jitter);
            tracker.learn_noise();
        }
        let sigma = tracker.noise_px().expect("learnt");
        assert!((sigma - 0.05 / 2f64.sqrt()).abs() < 1e-9, "{sigma}");
        // A slipping pattern whose peak is under the floor (SHEAR_FLOOR_SIGMAS σ) is noise.
        let (_, weak) = sheared(0.3, 0.9 * SHEAR_FLOOR_SIGMAS * sigma);
        tracker.track(&weak);
        let e = tracker.estimate((80.0, 80.0), 40.0, 0.05).expect("dots");
        assert_eq!((e.stick_ratio, e.state), (1.0, SlipState::None), "{e:?}");
        // Well above it, the slip shows.
        let (_, strong) = sheared(0.3, 40.0 * sigma);
        tracker.track(&strong);
        let e = tracker.estimate((80.0, 80.0), 40.0, 0.05).expect("dots");
        assert_eq!(e.state, SlipState::Incipient, "{e:?}");
    }

    #[test]
    fn the_tabled_profile_is_the_profile() {
        for k in 0..20_000 {
            let rho = k as f64 * 0.01;
            assert!(
                (tabled_profile(rho) - hertz_profile(rho)).abs() < 1e-3,
                "{rho}"
            );
            for s in [0.0, 0.3, 0.9] {
                assert!(
                    (tabled_shift(rho, s) - cattaneo_shift(rho, s)).abs() < 2e-3,
                    "{rho} {s}"
                );
            }
        }
        assert_eq!(tabled_profile(f64::NAN), 0.0);
    }

    #[test]
    fn a_dot_is_followed_from_where_it_was_last_seen() {
        let (mut tracker, frame) = sheared(0.0, 6.0);
        tracker.track(&frame);
        // Shifted further (past half the pitch from its reference place), it is still found.
        let further: Vec<Dot> = frame
            .iter()
            .zip(tracker.shifts())
            .map(|(d, (_, s))| {
                let (dx, _) = s.expect("found");
                Dot {
                    area_px: 20,
                    centre_px: (d.centre_px.0 + dx, d.centre_px.1),
                }
            })
            .collect();
        tracker.track(&further);
        let centre = tracker
            .shifts()
            .find(|(r, _)| *r == (80.0, 80.0))
            .and_then(|(_, s)| s);
        assert_eq!(centre, Some((12.0, 0.0)));
        tracker.track(&[]);
        assert!(tracker.shifts().all(|(_, s)| s.is_none()));
    }
}
