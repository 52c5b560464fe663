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
pub const FIT_STEPS: usize = 25;
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
    cells: std::collections::HashMap<(i64, i64), Vec<(f64, f64)>>,
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
            cells: std::collections::HashMap::new(),
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
        let key = |(x, y): (f64, f64)| ((x / cell).floor() as i64, (y / cell).floor() as i64);
        self.cells.values_mut().for_each(Vec::clear);
        for d in frame {
            self.cells
                .entry(key(d.centre_px))
                .or_default()
                .push(d.centre_px);
        }
        let reach = 0.5 * self.pitch_px;
        for (r, shift) in self.reference.iter().zip(self.shift.iter_mut()) {
            let (dx, dy) = shift.unwrap_or((0.0, 0.0));
            let at = (r.0 + dx, r.1 + dy);
            let (cx, cy) = key(at);
            let nearest = (cx - 1..=cx + 1)
                .flat_map(|x| (cy - 1..=cy + 1).map(move |y| (x, y)))
                .filter_map(|k| self.cells.get(&k))
                .flatten()
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
            let along: Vec<(f64, f64)> = near
                .iter()
                .map(|(r, s)| (distance(*r), field.along(*s)))
                .collect();
            fit_stick_ratio(&along, radius_px, noise)
        };
        Some(ShearEstimate {
            shear_mm: [mean.0 * mm_per_px, mean.1 * mm_per_px],
            stick_ratio,
            state: state_of(stick_ratio),
            dots_inside: inside.len(),
        })
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
    let extent = radius_px.max(1.0);
    let step = extent * (RADIUS_SPAN.1 - RADIUS_SPAN.0) / (RADII - 1) as f64;
    let coarse = (0..RADII).map(|j| extent * RADIUS_SPAN.0 + step * j as f64);
    let mut fits: Vec<(f64, f64, f64)> = coarse.flat_map(|r| fits_at(along, r)).collect();
    // Then finer around the best radius.
    let best_radius = fits
        .iter()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map_or(extent, |f| f.2);
    let fine = (0..RADII).map(|j| best_radius - step + 2.0 * step * j as f64 / (RADII - 1) as f64);
    fits.extend(fine.filter(|r| *r > 0.0).flat_map(|r| fits_at(along, r)));
    let best = fits.iter().map(|f| f.0).fold(f64::INFINITY, f64::min);
    let within = noise_px.map_or(FIT_TOLERANCE * best, |s| {
        (best + FIT_CONFIDENCE_SIGMAS2 * s * s).max(FIT_TOLERANCE * best)
    });
    let stick = fits
        .iter()
        .filter(|f| f.0 <= within)
        .map(|f| f.1)
        .fold(f64::NAN, f64::max);
    if stick.is_finite() { stick } else { 1.0 }
}

/// Every stick ratio's fit at contact radius `radius` px: (residual, stick ratio, radius).
fn fits_at(along: &[(f64, f64)], radius: f64) -> Vec<(f64, f64, f64)> {
    (0..=FIT_STEPS)
        .filter_map(|k| {
            let s = (k as f64 / FIT_STEPS as f64).min(MAX_FIT_STICK);
            let model: Vec<f64> = along
                .iter()
                .map(|(r, _)| tabled_shift(r / radius, s))
                .collect();
            let ff: f64 = model.iter().map(|f| f * f).sum();
            if ff <= 0.0 || !ff.is_finite() {
                return None;
            }
            let scale = along
                .iter()
                .zip(&model)
                .map(|((_, u), f)| u * f)
                .sum::<f64>()
                / ff;
            let residual: f64 = along
                .iter()
                .zip(&model)
                .map(|((_, u), f)| (u - scale * f).powi(2))
                .sum();
            Some((residual, s, radius))
        })
        .collect()
}

/// The contact radii tried by the fit, as shares of the depth map's, and how many (a small
/// ball's depth map reaches past its contact, into the gel sagging around it: 1.3× for a
/// 6 mm ball 1 mm deep).
const RADIUS_SPAN: (f64, f64) = (0.6, 1.25);
const RADII: usize = 9;
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
        let reference: Vec<(f64, f64)> = (0..9)
            .flat_map(|j| (0..9).map(move |i| (16.0 + 16.0 * i as f64, 16.0 + 16.0 * j as f64)))
            .collect();
        let frame = reference
            .iter()
            .map(|(x, y)| {
                let rho = (x - 80.0).hypot(y - 80.0) / 40.0;
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
