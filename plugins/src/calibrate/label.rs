//! Contact-circle detection: where a ball touched the gel in a press, from the press, the
//! sensor's no-contact background and the ball's size, to label calibration presses without
//! a person, on any sensor.
//!
//! Nothing here is a grey level seen on one sensor: every threshold is in units of the
//! dataset's own noise or of the frame's own spread, and every length in units of the ball's
//! radius (the image-processing scales, the blur and the background's smoothing, aside).
//! 1. the difference image, each channel divided by the background's local level (the LEDs'
//!    falloff across the pad) and less its median (a global brightness change),
//!    box-blurred, and its magnitude. Two noise figures come from the data: the frame's
//!    spread (MAD of the magnitude: its smooth shading and drift) and the camera's noise
//!    (what a 3×3 mean does not explain, per press; a dataset takes the median over its
//!    presses, [`Labeller::with_dataset_noise`]);
//! 2. the pixels above both form blobs (4-connected). Blobs within the ball's diameter of
//!    the largest are parts of one contact (the LEDs show some slope directions weakly, and
//!    a contact's magnitude may dip below the threshold there); a blob beyond that, of
//!    comparable size, is a second contact. A contact whose peak is under [`SHALLOW_SNR`]
//!    times the camera's noise is too shallow;
//! 3. from the contact's centroid, [`RAYS`] rays out to 1.5 times the ball's radius: along
//!    each, the outer point where the magnitude falls half way from the untouched gel to the
//!    ray's own peak, moved to the colour's largest change near it; and, near it too, the
//!    step fitted to the camera's channels (`edge`: a line either side of a jump, blurred
//!    by the detector's own box across a circular rim). Where the contact's rim is a step
//!    (its median ray's jump at least a quarter of the ray's peak: the simulator's gel,
//!    whose slope jumps to flat at the rim), the fitted steps are the rim; where it is not
//!    (a real gel's slope runs on past the contact), the falls are, or, where the
//!    dataset's presses show a gel whose surface sinks around the contact (the colour's
//!    path turns back at the contact's edge, and those turns grow with the imprints from
//!    press to press, [`Labeller::with_dataset_rims`]), the turns;
//! 4. a least-squares circle through those rim points (outliers dropped, then refitted),
//!    and the rays cast again from its centre, [`ITERATIONS`] times. A circle as wide as the
//!    ball is refused: no press of that ball can make it.
//!
//! The score (0–1) is the share of rays that found the rim times how well the rim points
//! lie on the circle (`exp(−rms / (5% of r))`).

use crate::image::RgbImage;
use crate::markers::InkFill;

mod edge;
mod field;
mod fit;

pub use field::DiffField;

/// Rays cast from the centre.
pub const RAYS: usize = 72;
/// Times the rays are recast from the fitted centre.
pub const ITERATIONS: usize = 4;
/// Box-blur radius of the difference image, px.
pub const BLUR_PX: usize = 2;
/// Box-blur radius of the background's level that the difference is divided by, px: the
/// LEDs' falloff is smooth over tens of pixels, the camera's noise is not.
pub const BACKGROUND_SMOOTH_PX: usize = 8;
/// Where on its way down from the ray's peak to the untouched gel a ray's rim is placed:
/// half way, where a step blurred by the optics sits.
pub const RIM_FRACTION: f64 = 0.5;
/// The frame's spreads (MAD × 1.4826 of the magnitude) above its median that count as
/// signal.
pub const SIGNAL_SIGMAS: f64 = 8.0;
/// The camera noise's spreads in the blurred magnitude that count as signal at least.
pub const NOISE_SIGMAS: f64 = 5.0;
/// A contact whose peak is less than this many times the camera noise in the magnitude is
/// too shallow to place a rim on.
pub const SHALLOW_SNR: f64 = 10.0;
/// A blob needs this many pixels to count.
pub const MIN_BLOB_PX: usize = 12;
/// A second blob, beyond the ball's diameter from the first, at least this share of its
/// size is a second contact.
pub const SECOND_BLOB_SHARE: f64 = 0.2;
/// Smallest contact radius that is labelled, in units of the ball's radius.
pub const MIN_RADIUS_SHARE: f64 = 0.08;
/// Share of the blob's pixels that may be clipped (a channel at 0 or 255 that is not so in
/// the background) before the press is saturated.
pub const SATURATED_SHARE: f64 = 0.02;
/// Least share of rays that must find the rim.
pub const MIN_RAY_SHARE: f64 = 0.5;

/// A detected contact circle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactCircle {
    /// Centre, px (x along columns, pixel centres at integers).
    pub center_x_px: f64,
    /// Centre, px (y along rows).
    pub center_y_px: f64,
    /// Contact radius, px.
    pub contact_radius_px: f64,
    /// Confidence, 0–1.
    pub score: f64,
}

/// Why a press was not labelled. Each has a stable `code` (`--json`'s `rejected[].code`)
/// and a text that gives what was measured.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Rejection {
    /// The image could not be read.
    #[error("unreadable: {detail}")]
    Unreadable {
        /// The decoder's error.
        detail: String,
    },
    /// The press and the background differ in size.
    #[error("wrong size: {width}x{height} px, the background is {bg_width}x{bg_height} px")]
    WrongSize {
        /// The press's columns.
        width: usize,
        /// The press's rows.
        height: usize,
        /// The background's columns.
        bg_width: usize,
        /// The background's rows.
        bg_height: usize,
    },
    /// Nothing above the noise.
    #[error(
        "no contact: nothing above the threshold ({threshold:.1} grey levels over the gel's \
         {baseline:.1}; camera noise {noise:.2} grey levels)"
    )]
    NoContact {
        /// The signal threshold, grey levels.
        threshold: f64,
        /// The untouched gel's magnitude, grey levels.
        baseline: f64,
        /// The camera's noise, grey levels per channel.
        noise: f64,
    },
    /// Something above the noise, but no round rim around it.
    #[error(
        "no contact: no round rim (found on {rays_found} of {rays} rays, {rms_px:.1} px RMS off \
         a circle)"
    )]
    NotRound {
        /// Rays that found the rim.
        rays_found: usize,
        /// Rays cast.
        rays: usize,
        /// RMS distance of the rim points from the circle, px.
        rms_px: f64,
    },
    /// More than one contact.
    #[error(
        "several contacts: one of {second_px} px {distance_px:.0} px from one of {first_px} px, \
         further apart than the ball's diameter ({diameter_px:.0} px)"
    )]
    SeveralContacts {
        /// The largest blob's size, px.
        first_px: usize,
        /// The second's, px.
        second_px: usize,
        /// Between their centroids, px.
        distance_px: f64,
        /// The ball's diameter, px.
        diameter_px: f64,
    },
    /// The contact runs off the image.
    #[error("cut by the border: {detail}")]
    CutByBorder {
        /// Where.
        detail: String,
    },
    /// Too faint or too small to place a rim on.
    #[error("too shallow: {detail}")]
    TooShallow {
        /// What was measured, against what.
        detail: String,
    },
    /// Clipped channels over the contact.
    #[error("saturated: {percent:.0}% of the contact's pixels are clipped at 0 or 255")]
    Saturated {
        /// Clipped share of the blob, %.
        percent: f64,
    },
    /// The contact is at least as wide as the ball.
    #[error(
        "larger than the ball: contact radius {radius_px:.1} px, the ball's {ball_radius_px:.1} \
         px (check --ball-mm and --mm-per-px)"
    )]
    LargerThanBall {
        /// The circle found, px.
        radius_px: f64,
        /// The ball's radius, px.
        ball_radius_px: f64,
    },
}

impl Rejection {
    /// The reason's stable code: `no_contact`, `several_contacts`, `cut_by_border`,
    /// `too_shallow`, `saturated`, `larger_than_ball`, `unreadable` or `wrong_size`.
    pub fn code(&self) -> &'static str {
        match self {
            Self::Unreadable { .. } => "unreadable",
            Self::WrongSize { .. } => "wrong_size",
            Self::NoContact { .. } | Self::NotRound { .. } => "no_contact",
            Self::SeveralContacts { .. } => "several_contacts",
            Self::CutByBorder { .. } => "cut_by_border",
            Self::TooShallow { .. } => "too_shallow",
            Self::Saturated { .. } => "saturated",
            Self::LargerThanBall { .. } => "larger_than_ball",
        }
    }
}

/// Labels presses of one ball against one background, with the dataset's noise.
#[derive(Debug, Clone)]
pub struct Labeller<'a> {
    /// The background, its marker dots filled when it shows a marker gel.
    background: std::borrow::Cow<'a, RgbImage>,
    ball_radius_px: f64,
    camera_noise: Option<f64>,
    /// A marker gel's dots, filled in every press before it is read.
    ink: Option<InkFill>,
    /// How the colour's turns moved with the imprints over the dataset: where they grow
    /// with them ([`RimSlope::turns_are_rims`]), rims that are not a step are read there.
    rim_slope: Option<RimSlope>,
}

impl<'a> Labeller<'a> {
    /// A labeller for presses of a ball of `ball_radius_px` against `background`; each press
    /// is measured against its own camera noise until [`Self::with_dataset_noise`].
    /// A marker gel's dots (found on the background) are filled in the background and in
    /// every press before either is read.
    pub fn new(background: &'a RgbImage, ball_radius_px: f64) -> Self {
        let (w, h) = (background.width, background.height);
        let values: Vec<f32> = background.data.iter().map(|v| f32::from(*v)).collect();
        let mut ink = InkFill::detect(&values, w, h);
        let background = match &mut ink {
            Some(fill) => {
                let mut filled = background.clone();
                fill.fill_u8(&mut filled.data);
                std::borrow::Cow::Owned(filled)
            }
            None => std::borrow::Cow::Borrowed(background),
        };
        Self {
            background,
            ball_radius_px,
            camera_noise: None,
            ink,
            rim_slope: None,
        }
    }

    /// `press` as the labeller reads it: its marker dots filled on a marker gel.
    fn read<'p>(&self, press: &'p RgbImage) -> std::borrow::Cow<'p, RgbImage> {
        match (&self.ink, same_size(press, &self.background)) {
            (Some(ink), true) => {
                let mut filled = press.clone();
                ink.clone().fill_u8(&mut filled.data);
                std::borrow::Cow::Owned(filled)
            }
            _ => std::borrow::Cow::Borrowed(press),
        }
    }

    /// Measure every press against the dataset's camera noise: the median of `presses`'
    /// own (those of the background's size).
    pub fn with_dataset_noise(mut self, presses: &[&RgbImage]) -> Self {
        let mut noise: Vec<f64> = presses
            .iter()
            .filter(|p| same_size(p, &self.background))
            .map(|p| DiffField::new(&self.read(p), &self.background, BLUR_PX).camera_noise())
            .filter(|n| n.is_finite())
            .collect();
        noise.sort_by(f64::total_cmp);
        self.camera_noise = noise.get(noise.len() / 2).copied();
        self
    }

    /// Read the rims of presses whose rim is not a step where the dataset says they are
    /// ([`rim_slope`] of `presses`' two readings): at the colour's turns when those move
    /// with the imprint from press to press, else where the imprint fades (as before this
    /// is called).
    pub fn with_dataset_rims(mut self, presses: &[&RgbImage]) -> Self {
        let pairs: Vec<(f64, f64)> = presses
            .iter()
            .filter_map(|p| detect::rim_radii(&self, &self.read(p)))
            .collect();
        self.rim_slope = rim_slope(&pairs, self.ball_radius_px);
        self
    }

    /// How the dataset's colour turns moved with its imprints ([`Self::with_dataset_rims`];
    /// `None`: not measured, or too few presses to tell).
    pub fn rim_slope(&self) -> Option<RimSlope> {
        self.rim_slope
    }

    /// Whether rims that are not a step are read at the colour's turns.
    fn turn_rims(&self) -> bool {
        self.rim_slope.is_some_and(|s| s.turns_are_rims())
    }

    /// The dataset's camera noise, grey levels per channel (`None`: each press's own).
    pub fn camera_noise(&self) -> Option<f64> {
        self.camera_noise
    }

    /// The ball's radius, px.
    pub fn ball_radius_px(&self) -> f64 {
        self.ball_radius_px
    }

    /// Find the contact circle of `press`.
    pub fn detect(&self, press: &RgbImage) -> Result<ContactCircle, Rejection> {
        detect::contact(self, &self.read(press))
    }
}

/// The least presses whose two rim readings decide where a dataset's rims are.
pub const MIN_RIM_PAIRS: usize = 5;
/// The imprints' radii must spread by at least this share of the ball's radius (their
/// standard deviation) for the turns' following them to be measured.
pub const MIN_IMPRINT_SPREAD: f64 = 0.05;
/// The turns are the rims when the log-log slope of their radii on the imprints' (the
/// median of the slopes between every two presses, so that a few misread presses do not
/// sway it) is at least this: 1 where they grow in proportion (a contact inside a wider
/// imprint), 0 where they stay put (an LED response turning over at one slope: a ball's
/// slope is a function of the distance from its centre alone, so that turn is at one
/// radius in every press).
pub const TURN_FOLLOWS_SLOPE: f64 = 0.5;

/// How a dataset's colour turns move with its imprints: the median log-log slope of the
/// turns' radii on the imprints' over `presses` presses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RimSlope {
    /// Presses measured.
    pub presses: usize,
    /// The slope (1: in proportion; 0: the turns stay put).
    pub slope: f64,
}

impl RimSlope {
    /// Whether the turns are the contact's rims (the slope at least [`TURN_FOLLOWS_SLOPE`]).
    pub fn turns_are_rims(&self) -> bool {
        self.slope >= TURN_FOLLOWS_SLOPE
    }
}

/// How the colour's turns move with the imprints, from a dataset's presses' `(imprint,
/// turn)` radii (px; `detect::rim_radii`), over the presses whose turn lies inside the
/// imprint (no contact is wider than what it leaves); `None` when that cannot be told:
/// fewer than [`MIN_RIM_PAIRS`] such presses, or imprints that spread by less than
/// [`MIN_IMPRINT_SPREAD`] of the ball's radius `ball_px`.
pub fn rim_slope(pairs: &[(f64, f64)], ball_px: f64) -> Option<RimSlope> {
    let inside: Vec<(f64, f64)> = pairs
        .iter()
        .copied()
        .filter(|(imprint, turn)| *turn > 0.0 && turn < imprint && imprint.is_finite())
        .collect();
    if inside.len() < MIN_RIM_PAIRS {
        return None;
    }
    let n = inside.len() as f64;
    let mean = inside.iter().map(|p| p.0).sum::<f64>() / n;
    let spread = (inside.iter().map(|p| (p.0 - mean).powi(2)).sum::<f64>() / n).sqrt();
    if spread
        .partial_cmp(&(MIN_IMPRINT_SPREAD * ball_px))
        .is_none_or(std::cmp::Ordering::is_lt)
    {
        return None;
    }
    let logs: Vec<(f64, f64)> = inside.iter().map(|(a, b)| (a.ln(), b.ln())).collect();
    let mut slopes: Vec<f64> = logs
        .iter()
        .enumerate()
        .flat_map(|(i, a)| logs[i + 1..].iter().map(move |b| (a, b)))
        .filter(|(a, b)| (b.0 - a.0).abs() > 1e-9)
        .map(|(a, b)| (b.1 - a.1) / (b.0 - a.0))
        .collect();
    if slopes.is_empty() {
        return None;
    }
    slopes.sort_by(f64::total_cmp);
    let median = slopes[slopes.len() / 2];
    Some(RimSlope {
        presses: inside.len(),
        slope: median,
    })
}

fn same_size(a: &RgbImage, b: &RgbImage) -> bool {
    (a.width, a.height) == (b.width, b.height) && a.data.len() == b.data.len()
}

/// Find the contact circle of `press` against `background`, for a ball of `ball_radius_px`
/// (the press measured against its own camera noise).
pub fn detect(
    press: &RgbImage,
    background: &RgbImage,
    ball_radius_px: f64,
) -> Result<ContactCircle, Rejection> {
    Labeller::new(background, ball_radius_px).detect(press)
}

mod detect;

#[cfg(test)]
mod tests;
