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
//! centroid, the dots within 2a give the shift's pattern. Cattaneo–Mindlin's shift along
//! the load, U/2 · (H(r/a) − s² H(r/(sa))) ([`cattaneo_shift`]), is fitted to their shifts
//! along the mean shift's direction over the stick ratio s (a grid of [`FIT_STEPS`]
//! values; U in closed form for each). A contact whose dots inside it moved less than
//! [`SHEAR_FLOOR_PX`] on the mean carries no load that the dots can tell: stick ratio 1.

use gelgrip_controller::markers::cattaneo_shift;

/// Mean shifts under this, px, are the dots' own noise (their centres are found to about a
/// twentieth of a pixel): no shear.
pub const SHEAR_FLOOR_PX: f64 = 0.25;
/// A contact slips incipiently below this estimated stick ratio.
pub const INCIPIENT_STICK_RATIO: f64 = 0.9;
/// A contact slides (gross slip) below this estimated stick ratio.
pub const GROSS_STICK_RATIO: f64 = 0.15;
/// Stick ratios tried by the fit (0, 1/FIT_STEPS, … below 1).
pub const FIT_STEPS: usize = 25;
/// Dots out to this many contact radii enter the fit.
const FIT_REACH: f64 = 2.0;

/// What a contact's slip looks like.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SlipState {
    /// Sticking.
    #[default]
    None,
    /// Its rim slides, its centre sticks.
    Incipient,
    /// It slides.
    Gross,
}

impl SlipState {
    /// The report's name.
    pub fn as_str(self) -> &'static str {
        match self {
            SlipState::None => "none",
            SlipState::Incipient => "incipient",
            SlipState::Gross => "gross",
        }
    }
}

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

    /// The shear under a contact centred at `centre_px` of radius `radius_px`, at
    /// `mm_per_px`; `None` without dots inside it.
    pub fn estimate(
        &self,
        centre_px: (f64, f64),
        radius_px: f64,
        mm_per_px: f64,
    ) -> Option<ShearEstimate> {
        if !(radius_px > 0.0 && radius_px.is_finite() && mm_per_px > 0.0) {
            return None;
        }
        let near: Vec<(f64, (f64, f64))> = self
            .shifts()
            .filter_map(|(r, s)| {
                let rho = (r.0 - centre_px.0).hypot(r.1 - centre_px.1) / radius_px;
                s.filter(|_| rho <= FIT_REACH).map(|s| (rho, s))
            })
            .collect();
        let inside: Vec<(f64, f64)> = near
            .iter()
            .filter(|(rho, _)| *rho <= 1.0)
            .map(|n| n.1)
            .collect();
        if inside.is_empty() {
            return None;
        }
        let n = inside.len() as f64;
        let mean = (
            inside.iter().map(|s| s.0).sum::<f64>() / n,
            inside.iter().map(|s| s.1).sum::<f64>() / n,
        );
        let size = mean.0.hypot(mean.1);
        let stick_ratio = if size < SHEAR_FLOOR_PX {
            1.0
        } else {
            let along: Vec<(f64, f64)> = near
                .iter()
                .map(|(rho, s)| (*rho, (s.0 * mean.0 + s.1 * mean.1) / size))
                .collect();
            fit_stick_ratio(&along)
        };
        let state = if stick_ratio < GROSS_STICK_RATIO {
            SlipState::Gross
        } else if stick_ratio < INCIPIENT_STICK_RATIO {
            SlipState::Incipient
        } else {
            SlipState::None
        };
        Some(ShearEstimate {
            shear_mm: [mean.0 * mm_per_px, mean.1 * mm_per_px],
            stick_ratio,
            state,
            dots_inside: inside.len(),
        })
    }
}

/// The stick ratio whose Cattaneo–Mindlin shift pattern fits `along` (radii from the centre
/// in units of the contact's area radius, shift along the load) best in least squares, its
/// scale free and the contact's radius free within [`RADIUS_SHARES`] of the area's (a
/// depth map's contact takes in the shallow gel around the ball).
fn fit_stick_ratio(along: &[(f64, f64)]) -> f64 {
    let mut best = (f64::INFINITY, 1.0);
    for share in RADIUS_SHARES {
        for k in 0..FIT_STEPS {
            let s = k as f64 / FIT_STEPS as f64;
            let model: Vec<f64> = along
                .iter()
                .map(|(rho, _)| cattaneo_shift(rho / share, s))
                .collect();
            let ff: f64 = model.iter().map(|f| f * f).sum();
            if ff <= 0.0 {
                continue;
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
            if residual < best.0 {
                best = (residual, s);
            }
        }
    }
    best.1
}

/// The contact radii tried by the fit, as shares of the radius of the contact's area.
const RADIUS_SHARES: [f64; 5] = [0.4, 0.55, 0.7, 0.85, 1.0];

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
            assert!((e.stick_ratio - s).abs() <= 0.05, "{s}: {e:?}");
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
