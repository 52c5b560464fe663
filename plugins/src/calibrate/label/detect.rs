//! The detection itself, step by step as the module above describes it: the field, the
//! contact's blobs, its shallowness, and the rim's circle within the ball.

use crate::image::RgbImage;

use super::field::{Blob, DiffField, RimPoints};
use super::fit;
use super::{
    BLUR_PX, ContactCircle, ITERATIONS, Labeller, MIN_RADIUS_SHARE, MIN_RAY_SHARE, RAYS, Rejection,
    SATURATED_SHARE, SECOND_BLOB_SHARE, SHALLOW_SNR, same_size,
};

/// A press's contact located: its field, the threshold and noise unit it was read at, and
/// its blob.
struct Located {
    field: DiffField,
    threshold: f64,
    noise_unit: f64,
    main: Blob,
}

impl Located {
    /// Rim points read around `centre` (the imprint's, or the turns', see
    /// [`DiffField::turn_points`]).
    fn points(&self, centre: (f64, f64), ball_px: f64, turns: bool) -> RimPoints {
        let (f, t, u) = (&self.field, self.threshold, self.noise_unit);
        if turns {
            f.turn_points(centre, ball_px, RAYS, t, u)
        } else {
            f.rim_points(centre, ball_px, RAYS, t, u)
        }
    }
}

/// The field of `press` and its one contact, checked for size, saturation and depth.
fn locate(labeller: &Labeller<'_>, press: &RgbImage) -> Result<Located, Rejection> {
    let background: &RgbImage = &labeller.background;
    if !same_size(press, background) {
        return Err(Rejection::WrongSize {
            width: press.width,
            height: press.height,
            bg_width: background.width,
            bg_height: background.height,
        });
    }
    let ball_px = labeller.ball_radius_px;
    let field = DiffField::new(press, background, BLUR_PX);
    // A frame clipped nearly everywhere (LEDs off, an overexposed camera) shows no press.
    let everywhere: Vec<usize> = (0..press.width * press.height).step_by(7).collect();
    let clipped = field.clipped_share(press, background, &everywhere);
    if clipped > 0.5 {
        return Err(Rejection::Saturated {
            percent: clipped * 100.0,
        });
    }
    let noise = labeller
        .camera_noise
        .unwrap_or_else(|| field.camera_noise());
    let threshold = field.threshold(noise);
    let main = one_contact(&field, threshold, noise, ball_px)?;
    let clipped = field.clipped_share(press, background, &main.pixels);
    if clipped > SATURATED_SHARE {
        return Err(Rejection::Saturated {
            percent: clipped * 100.0,
        });
    }
    let peak = main.peak - field.baseline();
    let unit = field.magnitude_noise(noise);
    if peak < SHALLOW_SNR * unit {
        return Err(Rejection::TooShallow {
            detail: format!(
                "peak {peak:.1} grey levels over the gel, {:.0} times the camera noise in it \
                 ({unit:.2}); {SHALLOW_SNR} needed",
                peak / unit
            ),
        });
    }
    Ok(Located {
        field,
        threshold,
        noise_unit: unit,
        main,
    })
}

/// Find the contact circle of `press` with `labeller`'s background, ball, noise and rims.
pub(super) fn contact(
    labeller: &Labeller<'_>,
    press: &RgbImage,
) -> Result<ContactCircle, Rejection> {
    let ball_px = labeller.ball_radius_px;
    let located = locate(labeller, press)?;
    let main = &located.main;
    let rim = |centre| located.points(centre, ball_px, false);
    let (circle, stepped) = match rim_circle(rim, main.centroid) {
        // Rays that run off the image find no rim there.
        Err(Rejection::NotRound { rays_found, .. }) if main.touches_border => {
            return Err(Rejection::CutByBorder {
                detail: format!(
                    "the contact reaches the image's edge (its rim found on {rays_found} of \
                     {RAYS} rays)"
                ),
            });
        }
        found => found?,
    };
    // On a gel whose rims are its colour's turns, the contact inside the imprint; the
    // imprint's circle where no round one is found there (refused if as wide as the ball).
    let circle = if labeller.turn_rims() && !stepped {
        let centre = (circle.center_x_px, circle.center_y_px);
        let turns = |c| located.points(c, ball_px, true);
        rim_circle(turns, centre).map_or(circle, |(inner, _)| inner)
    } else {
        circle
    };
    check_circle(&circle, ball_px, press)?;
    // The blob is the blurred signal: it reaches the border when the contact does, or
    // when the contact comes within the blur's reach (and the camera's) of it. The rays
    // towards the border found the rim or were dropped; a contact cut by the border has
    // its circle run past the edge, one beside it keeps the blur's reach inside.
    if main.touches_border && !inside_by(&circle, BLUR_PX as f64, press) {
        return Err(Rejection::CutByBorder {
            detail: format!(
                "the contact reaches the image's edge (its circle at ({:.1}, {:.1}) px, radius \
                 {:.1} px, within the blur's {BLUR_PX} px of it)",
                circle.center_x_px, circle.center_y_px, circle.contact_radius_px
            ),
        });
    }
    Ok(circle)
}

/// A press's two rim readings where its rim is not a step: the radius of the imprint's
/// circle (each ray's fall) and of the circle through the colour's turns, px; `None` for a
/// press that is refused, whose rim is a step, or where either circle is not found.
pub(super) fn rim_radii(labeller: &Labeller<'_>, press: &RgbImage) -> Option<(f64, f64)> {
    let ball_px = labeller.ball_radius_px;
    let located = locate(labeller, press).ok()?;
    let rim = |centre| located.points(centre, ball_px, false);
    let (imprint, stepped) = rim_circle(rim, located.main.centroid).ok()?;
    if stepped {
        return None;
    }
    let centre = (imprint.center_x_px, imprint.center_y_px);
    let turns = |c| located.points(c, ball_px, true);
    let (turn, _) = rim_circle(turns, centre).ok()?;
    Some((imprint.contact_radius_px, turn.contact_radius_px))
}

/// The blobs above `threshold` as one contact: those within the ball's diameter of the
/// largest are its parts; another as large beyond it is a second contact.
fn one_contact(
    field: &DiffField,
    threshold: f64,
    noise: f64,
    ball_px: f64,
) -> Result<Blob, Rejection> {
    let mut blobs = field.blobs(threshold).into_iter();
    let Some(mut main) = blobs.next() else {
        return Err(Rejection::NoContact {
            threshold: threshold - field.baseline(),
            baseline: field.baseline(),
            noise,
        });
    };
    let diameter_px = 2.0 * ball_px;
    let first = main.centroid;
    let mut parts = Vec::new();
    for blob in blobs {
        let distance_px = (blob.centroid.0 - first.0).hypot(blob.centroid.1 - first.1);
        if distance_px <= diameter_px {
            parts.push(blob);
        } else if blob.pixels.len() as f64 >= SECOND_BLOB_SHARE * main.pixels.len() as f64 {
            return Err(Rejection::SeveralContacts {
                first_px: main.pixels.len(),
                second_px: blob.pixels.len(),
                distance_px,
                diameter_px,
            });
        }
    }
    for part in parts {
        main = field.merge(main, part, threshold);
    }
    Ok(main)
}

/// The circle through the rim points that `points` reads around a centre, rays recast
/// from each fit's centre (the first from `centroid`), and whether the last reading's rim
/// was a step.
fn rim_circle(
    points: impl Fn((f64, f64)) -> RimPoints,
    centroid: (f64, f64),
) -> Result<(ContactCircle, bool), Rejection> {
    let (mut cx, mut cy) = centroid;
    let mut r = f64::NAN;
    let mut found = (0, f64::NAN);
    let mut stepped = false;
    for _ in 0..ITERATIONS {
        let reading = points((cx, cy));
        stepped = reading.stepped;
        let rim = reading.points;
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
    let score = rays_found as f64 / RAYS as f64 * (-rms_px / (0.05 * r)).exp();
    let circle = ContactCircle {
        center_x_px: cx,
        center_y_px: cy,
        contact_radius_px: r,
        score: if score.is_finite() {
            score.clamp(0.0, 1.0)
        } else {
            0.0
        },
    };
    Ok((circle, stepped))
}

/// The circle's size against the ball's and its place against the image's border.
fn check_circle(c: &ContactCircle, ball_px: f64, press: &RgbImage) -> Result<(), Rejection> {
    let (cx, cy, r) = (c.center_x_px, c.center_y_px, c.contact_radius_px);
    if !(r.is_finite() && cx.is_finite() && cy.is_finite()) || r < MIN_RADIUS_SHARE * ball_px {
        return Err(Rejection::TooShallow {
            detail: format!(
                "contact radius {r:.1} px, under {MIN_RADIUS_SHARE} of the ball's {ball_px:.1} px"
            ),
        });
    }
    if r >= ball_px {
        return Err(Rejection::LargerThanBall {
            radius_px: r,
            ball_radius_px: ball_px,
        });
    }
    if !inside_by(c, 0.0, press) {
        return Err(Rejection::CutByBorder {
            detail: format!(
                "the circle at ({cx:.1}, {cy:.1}) px, radius {r:.1} px, runs past the {}x{} image",
                press.width, press.height
            ),
        });
    }
    Ok(())
}

/// Whether circle `c` lies inside `press` with `margin_px` to spare.
fn inside_by(c: &ContactCircle, margin_px: f64, press: &RgbImage) -> bool {
    let (cx, cy, r) = (
        c.center_x_px,
        c.center_y_px,
        c.contact_radius_px + margin_px,
    );
    let (w, h) = (press.width as f64, press.height as f64);
    cx - r >= 0.0 && cy - r >= 0.0 && cx + r <= w - 1.0 && cy + r <= h - 1.0
}
