//! Contact-circle detection: where a ball touched the gel in a press, from the press and the
//! sensor's no-contact background, to label calibration presses without a person.
//!
//! The contact's rim is where the gel's slope is steepest and then stops: the difference
//! from the background (its magnitude over the three channels) steps down there. Optics blur
//! that step, and the LEDs make its height depend on the direction the slope faces, so the
//! rim is found ray by ray, each relative to its own height and the contact's:
//! 1. the difference image, each channel divided by the background's local level (the LEDs'
//!    falloff across the pad) and less its median (a global brightness change),
//!    box-blurred, and its magnitude; the noise level is the magnitude's median and spread
//!    (MAD) over the frame;
//! 2. the pixels above the noise form blobs (4-connected): none is "no contact", a second
//!    one of comparable size "two blobs", clipped channels over the blob (or over half the
//!    frame) "saturated";
//! 3. from the blob's centroid, [`RAYS`] rays: along each, the outer point where the
//!    magnitude falls half way from the untouched gel to a reference height (a step blurred
//!    by the optics is at half height at the step), interpolated between samples. The
//!    reference is the geometric mean of the ray's own peak (the LEDs show slopes facing
//!    some ways more strongly than others) and the contact's (on a real sensor the weakly
//!    shown directions are also the broad ones, and read against their own peak they pull
//!    the centre toward them: 7 px on the GelSight Mini);
//! 4. a least-squares circle through those rim points (outliers dropped, then refitted),
//!    and the rays cast again from its centre, [`ITERATIONS`] times.
//!
//! The score (0–1) is the share of rays that found the rim times how well the rim points
//! lie on the circle (`exp(−rms / (5% of r))`).

use crate::image::RgbImage;

mod field;
mod fit;

pub use field::DiffField;

/// Rays cast from the centre.
pub const RAYS: usize = 72;
/// Times the rays are recast from the fitted centre.
pub const ITERATIONS: usize = 3;
/// Box-blur radius of the difference image, px.
pub const BLUR_PX: usize = 2;
/// Box-blur radius of the background's level that the difference is divided by, px: the
/// LEDs' falloff is smooth over tens of pixels, the camera's noise is not.
pub const BACKGROUND_SMOOTH_PX: usize = 8;
/// Where on its way down from the reference height to the untouched gel a ray's rim is
/// placed: half way, where a step blurred by the optics sits. A real GelSight Mini shows
/// no step (its colour change fades over tens of pixels) and there the level sets the
/// radius: 0.4 would match the mean size of its authors' hand-drawn circles, but moves the
/// simulator's rims 0.7 px outward (docs/calibration.md).
pub const RIM_FRACTION: f64 = 0.5;
/// Noise spreads (MAD × 1.4826) above the median magnitude that count as signal.
pub const SIGNAL_SIGMAS: f64 = 8.0;
/// The least magnitude that counts as signal, grey levels (a noise-free synthetic frame has
/// no spread to scale).
pub const MIN_SIGNAL: f64 = 4.0;
/// A blob needs this many pixels to count.
pub const MIN_BLOB_PX: usize = 12;
/// A second blob at least this share of the largest one's size makes two blobs.
pub const SECOND_BLOB_SHARE: f64 = 0.2;
/// A contact whose peak is less than this many times the signal threshold is too shallow to
/// place a rim on.
pub const SHALLOW_PEAK: f64 = 2.5;
/// Smallest contact radius that is labelled, px.
pub const MIN_RADIUS_PX: f64 = 3.0;
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

/// Why a press was not labelled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Rejection {
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
    #[error("no contact: nothing above the noise (threshold {threshold:.1} grey levels)")]
    NoContact {
        /// The signal threshold, grey levels.
        threshold: f64,
    },
    /// More than one contact.
    #[error("two blobs: a second contact of {second_px} px beside one of {first_px} px")]
    TwoBlobs {
        /// The largest blob's size, px.
        first_px: usize,
        /// The second's, px.
        second_px: usize,
    },
    /// The contact runs off the image.
    #[error("cut by the pad's edge: the contact reaches the image border")]
    CutByEdge,
    /// Too faint or too small to place a rim on.
    #[error("too shallow: {detail}")]
    TooShallow {
        /// What was too small.
        detail: String,
    },
    /// Clipped channels over the contact.
    #[error("saturated: {percent:.0}% of the contact's pixels are clipped at 0 or 255")]
    Saturated {
        /// Clipped share of the blob, %.
        percent: f64,
    },
    /// The rim is not a circle.
    #[error(
        "not round: the rim was found on {rays_found} of {rays} rays, {rms_px:.1} px RMS off the circle"
    )]
    NotRound {
        /// Rays that found the rim.
        rays_found: usize,
        /// Rays cast.
        rays: usize,
        /// RMS distance of the rim points from the circle, px.
        rms_px: f64,
    },
}

impl Rejection {
    /// The reason's short name (`no contact`, `two blobs`, …), without its figures.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::WrongSize { .. } => "wrong size",
            Self::NoContact { .. } => "no contact",
            Self::TwoBlobs { .. } => "two blobs",
            Self::CutByEdge => "cut by the pad's edge",
            Self::TooShallow { .. } => "too shallow",
            Self::Saturated { .. } => "saturated",
            Self::NotRound { .. } => "not round",
        }
    }
}

/// Find the contact circle of `press` against `background`.
pub fn detect(press: &RgbImage, background: &RgbImage) -> Result<ContactCircle, Rejection> {
    if (press.width, press.height) != (background.width, background.height)
        || press.data.len() != background.data.len()
    {
        return Err(Rejection::WrongSize {
            width: press.width,
            height: press.height,
            bg_width: background.width,
            bg_height: background.height,
        });
    }
    let field = DiffField::new(press, background, BLUR_PX);
    // A frame clipped nearly everywhere (LEDs off, an overexposed camera) shows no press.
    let everywhere: Vec<usize> = (0..press.width * press.height).step_by(7).collect();
    let clipped = field.clipped_share(press, background, &everywhere);
    if clipped > 0.5 {
        return Err(Rejection::Saturated {
            percent: clipped * 100.0,
        });
    }
    let threshold = field.threshold();
    let blobs = field.blobs(threshold);
    let Some(main) = blobs.first() else {
        return Err(Rejection::NoContact { threshold });
    };
    if let Some(second) = blobs.get(1)
        && second.pixels.len() as f64 >= SECOND_BLOB_SHARE * main.pixels.len() as f64
    {
        return Err(Rejection::TwoBlobs {
            first_px: main.pixels.len(),
            second_px: second.pixels.len(),
        });
    }
    let clipped = field.clipped_share(press, background, &main.pixels);
    if clipped > SATURATED_SHARE {
        return Err(Rejection::Saturated {
            percent: clipped * 100.0,
        });
    }
    if main.touches_border {
        return Err(Rejection::CutByEdge);
    }
    let peak = main.peak - field.baseline();
    if peak < SHALLOW_PEAK * (threshold - field.baseline()) {
        return Err(Rejection::TooShallow {
            detail: format!(
                "peak {peak:.1} grey levels, under {SHALLOW_PEAK} x the signal threshold"
            ),
        });
    }
    let (mut cx, mut cy) = main.centroid;
    let mut r = (main.pixels.len() as f64 / std::f64::consts::PI).sqrt();
    let mut found = (0, 0.0);
    for _ in 0..ITERATIONS {
        let reach = (2.5 * r).max(8.0);
        let rim = field.rim_points((cx, cy), reach, RAYS, threshold, main.peak);
        let Some(circle) = fit::robust_circle(&rim) else {
            return Err(Rejection::NotRound {
                rays_found: rim.len(),
                rays: RAYS,
                rms_px: f64::NAN,
            });
        };
        (cx, cy, r) = (circle.cx, circle.cy, circle.r);
        found = (rim.len(), circle.rms);
    }
    let (rays_found, rms_px) = found;
    if (rays_found as f64) < MIN_RAY_SHARE * RAYS as f64 || rms_px.is_nan() || rms_px >= 0.25 * r {
        return Err(Rejection::NotRound {
            rays_found,
            rays: RAYS,
            rms_px,
        });
    }
    if r.is_nan() || r < MIN_RADIUS_PX {
        return Err(Rejection::TooShallow {
            detail: format!("contact radius {r:.1} px, under {MIN_RADIUS_PX} px"),
        });
    }
    let (w, h) = (press.width as f64, press.height as f64);
    if cx - r < 0.0 || cy - r < 0.0 || cx + r > w - 1.0 || cy + r > h - 1.0 {
        return Err(Rejection::CutByEdge);
    }
    let score = rays_found as f64 / RAYS as f64 * (-rms_px / (0.05 * r)).exp();
    Ok(ContactCircle {
        center_x_px: cx,
        center_y_px: cy,
        contact_radius_px: r,
        score: if score.is_finite() {
            score.clamp(0.0, 1.0)
        } else {
            0.0
        },
    })
}

#[cfg(test)]
mod tests;
