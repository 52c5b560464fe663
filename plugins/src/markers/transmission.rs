//! The dots' ink as a transmission profile: the share of the gel's light each channel keeps
//! at a distance from a dot's centre, measured once on the reference over all its whole
//! dots, so that a frame's ink is divided out where the ink lets enough light through and
//! only the dark core is filled (docs/pipeline.md, "Marker gels").
//!
//! Filling a whole dot from the gel either side carries a contact's steep edge across it
//! when the dot straddles the edge; the soft rim around the core (its anti-aliasing, the
//! optics' blur, the JPEG's ringing) is most of a filled dot's pixels. A camera's pixel
//! under ink is the gel's light times the ink's transmission there, and that transmission
//! depends on where the pixel lies against the dot's centre, not on the light. Averaged
//! over every dot of the reference (the ratio of the reference to its line fill, per
//! distance bin), the profile carries none of one pixel's noise. A pixel whose transmission
//! is below [`MIN_TRANSMISSION`] (its noise multiplied more than three times) is left to the
//! line fill.

/// Width of one distance bin of the profile, px.
const BIN_PX: f64 = 0.1;
/// Pixels whose ink keeps less than this share of the light are filled, not divided: the
/// division would multiply their noise by more than its inverse.
pub const MIN_TRANSMISSION: f32 = 1.0 / 3.0;
/// A bin differs from clear gel when its mean is this many standard errors from 1.
const CLEAR_SIGMAS: f64 = 4.0;
/// Until the dots' noise is learnt, a dot found within this of its reference place has not
/// moved, px; after, within [`STILL_SIGMAS`] of the noise (and at least [`MIN_STILL_PX`]).
const UNLEARNT_STILL_PX: f64 = 0.5;
/// See [`UNLEARNT_STILL_PX`].
const STILL_SIGMAS: f64 = 4.0;
/// See [`UNLEARNT_STILL_PX`].
const MIN_STILL_PX: f64 = 0.25;

/// The ink's transmission against the distance from a dot's centre, and the working space
/// to place it on a frame's dots.
#[derive(Debug, Clone, PartialEq)]
pub struct InkTransmission {
    width: usize,
    height: usize,
    /// Per distance bin of [`BIN_PX`], each channel's share of the light kept.
    bins: Vec<[f32; 3]>,
    /// Beyond this distance from a dot's centre, the ink keeps all the light, px.
    reach_px: f64,
    /// Per pixel, the distance to the nearest placed dot's centre, px (infinite: none
    /// within reach).
    distance: Vec<f32>,
    /// Pixels whose distance the last placement set.
    placed: Vec<usize>,
}

impl InkTransmission {
    /// The profile of `reference` (interleaved RGB, `width × height`) against `filled` (the
    /// same frame with its ink filled from the gel around it), over the dots centred at
    /// `centres` (px, pixel centres at +0.5), out to half their `pitch_px`. `None` when no
    /// bin shows ink.
    pub fn measure(
        reference: &[f32],
        filled: &[u8],
        (width, height): (usize, usize),
        centres: &[(f64, f64)],
        pitch_px: f64,
    ) -> Option<Self> {
        let n_bins = (0.5 * pitch_px / BIN_PX).floor() as usize;
        if n_bins < 2 || reference.len() != width * height * 3 || filled.len() != reference.len() {
            return None;
        }
        let mut sums = vec![BinSums::default(); n_bins];
        for &centre in centres {
            for_each_near((width, height), centre, n_bins as f64 * BIN_PX, |p, d| {
                let bin = &mut sums[((d / BIN_PX) as usize).min(n_bins - 1)];
                let (fill, image) = (&filled[3 * p..3 * p + 3], &reference[3 * p..3 * p + 3]);
                if fill.iter().all(|v| *v > 0) && image.iter().all(|v| v.is_finite()) {
                    for c in 0..3 {
                        let t = f64::from(image[c]) / f64::from(fill[c]);
                        bin.sum[c] += t;
                        bin.squares[c] += t * t;
                    }
                    bin.distance_px += d;
                    bin.count += 1;
                }
            });
        }
        profile_of(&sums).map(|(bins, reach_px)| Self {
            width,
            height,
            bins,
            reach_px,
            distance: vec![f32::INFINITY; width * height],
            placed: Vec::new(),
        })
    }

    /// How far from a dot's centre its ink darkens the gel, px.
    pub fn reach_px(&self) -> f64 {
        self.reach_px
    }

    /// Place the profile on the dots of the last frame that sit where the reference had
    /// them: each reference dot (`at`) whose `shift` in the frame is within its noise
    /// (`noise_px`, per axis, once learnt). A dot that moved, or was not found, is left to
    /// the line fill: its rim is as steep as a pixel, and a centre a twentieth of a pixel
    /// off would misplace it by more than the camera's noise.
    pub fn place(
        &mut self,
        dots: impl Iterator<Item = ((f64, f64), Option<(f64, f64)>)>,
        noise_px: Option<f64>,
    ) {
        for p in self.placed.drain(..) {
            self.distance[p] = f32::INFINITY;
        }
        let still_px = noise_px
            .map(|s| (STILL_SIGMAS * s).max(MIN_STILL_PX))
            .unwrap_or(UNLEARNT_STILL_PX);
        let (distance, placed) = (&mut self.distance, &mut self.placed);
        let still =
            dots.filter(|(_, shift)| shift.is_some_and(|(dx, dy)| dx.hypot(dy) <= still_px));
        for (centre, _) in still {
            for_each_near((self.width, self.height), centre, self.reach_px, |p, d| {
                let d = d as f32;
                if distance[p].is_infinite() {
                    placed.push(p);
                }
                distance[p] = distance[p].min(d);
            });
        }
    }

    /// Divide the ink out of `rgb` (interleaved 8-bit) where the placed dots' ink lets
    /// enough light through, and flag in `ink` the pixels to fill (the dark cores); pixels
    /// no placed dot reaches keep their flag.
    pub fn apply(&self, rgb: &mut [u8], ink: &mut [bool]) {
        for &p in &self.placed {
            let t = self.at(f64::from(self.distance[p]));
            if t.iter().any(|v| *v < MIN_TRANSMISSION) {
                ink[p] = true;
                continue;
            }
            ink[p] = false;
            for (v, t) in rgb[3 * p..3 * p + 3].iter_mut().zip(t) {
                // Non-negative: adding a half and truncating rounds it.
                *v = (f32::from(*v) / t + 0.5).min(255.0) as u8;
            }
        }
    }

    /// Each channel's transmission at `distance_px` from a dot's centre (linear between the
    /// bins' centres; all the light beyond the profile's reach).
    fn at(&self, distance_px: f64) -> [f32; 3] {
        if distance_px >= self.reach_px {
            return [1.0; 3];
        }
        let x = (distance_px / BIN_PX - 0.5).max(0.0);
        let i = (x.floor() as usize).min(self.bins.len() - 1);
        let j = (i + 1).min(self.bins.len() - 1);
        let f = (x - i as f64).clamp(0.0, 1.0) as f32;
        [0, 1, 2].map(|c| self.bins[i][c] + (self.bins[j][c] - self.bins[i][c]) * f)
    }
}

/// Call `visit(pixel, distance)` for every pixel of a `w × h` frame whose centre lies within
/// `reach` px of `centre`.
fn for_each_near(
    (w, h): (usize, usize),
    centre: (f64, f64),
    reach: f64,
    mut visit: impl FnMut(usize, f64),
) {
    if !(centre.0.is_finite() && centre.1.is_finite()) {
        return;
    }
    let span = |c: f64, size: usize| {
        let lo = (c - reach - 0.5).floor().max(0.0) as usize;
        let hi = ((c + reach + 0.5).ceil().max(0.0) as usize).min(size);
        lo..hi
    };
    for y in span(centre.1, h) {
        for x in span(centre.0, w) {
            let d = (x as f64 + 0.5 - centre.0).hypot(y as f64 + 0.5 - centre.1);
            if d < reach {
                visit(y * w + x, d);
            }
        }
    }
}

/// One distance bin's pixels: per channel, the sums of their transmission and of its
/// square; the sum of their distances; how many.
#[derive(Debug, Clone, Copy, Default)]
struct BinSums {
    sum: [f64; 3],
    squares: [f64; 3],
    distance_px: f64,
    count: usize,
}

impl BinSums {
    /// The bin's mean distance and per-channel mean transmission (`None`: no pixels).
    fn mean(&self) -> Option<(f64, [f64; 3])> {
        let n = self.count as f64;
        (self.count > 0).then(|| (self.distance_px / n, self.sum.map(|v| v / n)))
    }

    /// Whether its mean differs from clear gel by more than [`CLEAR_SIGMAS`] standard
    /// errors in any channel.
    fn inked(&self) -> bool {
        let n = self.count as f64;
        self.count > 1
            && (0..3).any(|c| {
                let m = self.sum[c] / n;
                let spread = (self.squares[c] / n - m * m).max(0.0).sqrt();
                (m - 1.0).abs() > CLEAR_SIGMAS * spread / n.sqrt()
            })
    }
}

/// The profile from the bins' sums: at each bin's centre, the straight line between the
/// nearest bins' means either side (each at its pixels' mean distance; the nearer alone at
/// an end), out to the first bin with pixels past the last that differs from clear gel, and
/// that distance; `None` when none does.
fn profile_of(sums: &[BinSums]) -> Option<(Vec<[f32; 3]>, f64)> {
    let last = sums.iter().rposition(BinSums::inked)?;
    let end = (last + 1..sums.len())
        .find(|&i| sums[i].count > 0)
        .map_or(sums.len(), |i| i + 1);
    let points: Vec<(f64, [f64; 3])> = sums[..end].iter().filter_map(BinSums::mean).collect();
    let bins = (0..end)
        .map(|i| {
            let d = (i as f64 + 0.5) * BIN_PX;
            let after = points.iter().position(|p| p.0 >= d);
            let t = match after {
                Some(0) => points[0].1,
                Some(k) => {
                    let ((d0, t0), (d1, t1)) = (points[k - 1], points[k]);
                    let f = if d1 > d0 { (d - d0) / (d1 - d0) } else { 0.0 };
                    [0, 1, 2].map(|c| t0[c] + (t1[c] - t0[c]) * f)
                }
                None => points.last().map_or([1.0; 3], |p| p.1),
            };
            t.map(|v| v as f32)
        })
        .collect::<Vec<_>>();
    let reach_px = bins.len() as f64 * BIN_PX;
    Some((bins, reach_px))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 px gel of 200 with dots every 16 px whose ink (anti-aliased over the pixel
    /// around radius 3 px) keeps a quarter of the light, and the dots' centres.
    fn dotted() -> (Vec<f32>, Vec<(f64, f64)>) {
        let (w, h) = (64, 64);
        let centres: Vec<(f64, f64)> = (0..4)
            .flat_map(|j| (0..4).map(move |i| (8.0 + 16.0 * i as f64, 8.0 + 16.0 * j as f64)))
            .collect();
        let mut reference = vec![200.0f32; w * h * 3];
        for y in 0..h {
            for x in 0..w {
                let d = centres
                    .iter()
                    .map(|c| (x as f64 + 0.5 - c.0).hypot(y as f64 + 0.5 - c.1))
                    .fold(f64::INFINITY, f64::min);
                let cover = (3.5 - d).clamp(0.0, 1.0) as f32;
                reference[3 * (y * w + x)..3 * (y * w + x) + 3].fill(200.0 * (1.0 - 0.75 * cover));
            }
        }
        (reference, centres)
    }

    #[test]
    fn the_profile_is_the_dots_mean_and_ends_where_the_ink_does() {
        let (w, h) = (64, 64);
        let (reference, centres) = dotted();
        let filled = vec![200u8; w * h * 3];
        let ink = InkTransmission::measure(&reference, &filled, (w, h), &centres, 16.0)
            .expect("a profile");
        assert!((3.5..=3.75).contains(&ink.reach_px()), "{}", ink.reach_px());
        assert_eq!(ink.at(1.0), [0.25; 3]);
        assert!((ink.at(3.0)[0] - 0.625).abs() < 0.01, "{:?}", ink.at(3.0));
        assert_eq!(ink.at(5.0), [1.0; 3]);
        // Placed on a frame whose dots sit where the reference's did (within their
        // noise), it divides the rims back to the gel and flags the cores to fill.
        let mut ink = ink;
        ink.place(centres.iter().map(|c| (*c, Some((0.1, 0.0)))), None);
        let mut frame: Vec<u8> = reference.iter().map(|v| (v + 0.5) as u8).collect();
        let mut flags = vec![false; w * h];
        ink.apply(&mut frame, &mut flags);
        let cores = flags.iter().filter(|f| **f).count();
        // Below a third of the light: within about 2.9 px of each centre.
        assert!((16 * 21..=16 * 32).contains(&cores), "{cores}");
        let worst = frame
            .chunks_exact(3)
            .zip(&flags)
            .filter(|(_, f)| !**f)
            .map(|(v, _)| (i32::from(v[0]) - 200).abs())
            .max();
        assert!(worst.is_some_and(|v| v <= 2), "{worst:?}");
    }

    #[test]
    fn a_clear_reference_has_no_profile() {
        let (w, h) = (32, 32);
        let reference = vec![200.0f32; w * h * 3];
        let filled = vec![200u8; w * h * 3];
        let centres = [(16.0, 16.0)];
        assert_eq!(
            InkTransmission::measure(&reference, &filled, (w, h), &centres, 16.0),
            None
        );
        assert_eq!(
            InkTransmission::measure(&reference, &filled[..9], (w, h), &centres, 16.0),
            None
        );
    }

    #[test]
    fn a_shading_edge_across_a_still_dot_stays_where_it_is() {
        // The dotted gel, and a frame of it whose shading drops to 60% left of x = 24
        // (through the dots of the column at x = 24): the rims are divided back to the
        // gel's shading on each side, and only the cores are filled across the edge.
        let (w, h) = (64, 64);
        let (reference, _) = dotted();
        let mut fill = crate::markers::InkFill::detect(&reference, w, h).expect("dots");
        assert!(
            fill.ink_reach_px()
                .is_some_and(|r| (3.4..=3.8).contains(&r))
        );
        let step = |x: usize| if x < 24 { 0.6 } else { 1.0 };
        let shaded = |image: &[f32]| -> Vec<u8> {
            (0..w * h * 3)
                .map(|i| (image[i] * step((i / 3) % w) + 0.5) as u8)
                .collect()
        };
        let mut frame = shaded(&reference);
        fill.fill_u8(&mut frame);
        let plain = shaded(&vec![200.0; w * h * 3]);
        let wrong = frame
            .iter()
            .zip(&plain)
            .filter(|(a, b)| a.abs_diff(**b) > 4)
            .count()
            / 3;
        // The four dots on the edge: their cores (about 26 px each) at most, where a fill of
        // the whole dot and its rim (about 95 px each) would carry the edge across.
        assert!(wrong <= 4 * 30, "{wrong}");
    }
}
