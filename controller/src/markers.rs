//! Markers printed on a sensor's gel: a square grid of dark dots (`markers` in the layout),
//! as real GelSight gels carry them to show the surface's shear (docs/sim.md, "Markers").

use serde::Deserialize;

use crate::config::{ConfigError, FieldCheck};

/// A grid of dark dots on the gel, centred on the pad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarkerGrid {
    /// Centre-to-centre spacing, mm.
    pub pitch_mm: f64,
    /// Dot diameter, mm.
    pub dot_mm: f64,
}

/// The least dot the camera resolves, px across.
pub const MIN_DOT_PX: f64 = 3.0;
/// The least markers across the pad's shorter side.
pub const MIN_MARKERS_ACROSS: f64 = 3.0;
/// The dots are at most this share of the pitch across (gel left between them to see).
pub const MAX_DOT_SHARE: f64 = 0.6;

/// `markers = { pitch_mm, dot_mm }` as written.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMarkers {
    pitch_mm: f64,
    dot_mm: f64,
}

impl RawMarkers {
    /// Validated against the pad (`resolution` px at `mm_per_px`): dots at least
    /// [`MIN_DOT_PX`] across, at most [`MAX_DOT_SHARE`] of the pitch, and at least
    /// [`MIN_MARKERS_ACROSS`] of them across the pad; errors name `field`'s keys.
    pub fn validate(
        &self,
        check: &FieldCheck,
        field: &str,
        [width_px, height_px]: [u32; 2],
        mm_per_px: f64,
    ) -> Result<MarkerGrid, ConfigError> {
        let pad_mm = f64::from(width_px.min(height_px)) * mm_per_px;
        let pitch_mm = check.range(
            &format!("{field}.pitch_mm"),
            self.pitch_mm,
            MIN_DOT_PX * mm_per_px / MAX_DOT_SHARE,
            pad_mm / MIN_MARKERS_ACROSS,
        )?;
        let dot_mm = check.range(
            &format!("{field}.dot_mm"),
            self.dot_mm,
            MIN_DOT_PX * mm_per_px,
            MAX_DOT_SHARE * pitch_mm,
        )?;
        Ok(MarkerGrid { pitch_mm, dot_mm })
    }
}

/// The surface of an elastic half-space under a Hertz-type load of radius 1, at `rho`
/// radii from its centre, as a share of its value at the load's edge: 2 − ρ² inside, then
/// (2/π)((2 − ρ²) asin(1/ρ) + sqrt(ρ² − 1)), which meets it at 1 with the same slope and
/// falls as 8/(3πρ) far away. A marker gel's shift under a Cattaneo–Mindlin contact of
/// radius a and stick radius c is U/2 · (H(r/a) − (c/a)² H(r/c)): the simulator draws its
/// dots with it and the pipeline's slip estimate fits it.
pub fn hertz_profile(rho: f64) -> f64 {
    if !rho.is_finite() {
        return 0.0;
    }
    let rho = rho.abs();
    if rho <= 1.0 {
        return 2.0 - rho * rho;
    }
    let v = std::f64::consts::FRAC_2_PI
        * ((2.0 - rho * rho) * (1.0 / rho).asin() + (rho * rho - 1.0).sqrt());
    v.clamp(0.0, 1.0)
}

/// The shift profile of a contact of stick ratio `stick_ratio` at `rho` contact radii from
/// its centre, in units of U/2: H(ρ) − s² H(ρ/s) (0 at s = 1: no load).
pub fn cattaneo_shift(rho: f64, stick_ratio: f64) -> f64 {
    cattaneo_shift_of(hertz_profile, rho, stick_ratio)
}

/// [`cattaneo_shift`] with `profile` standing for H (a faster copy of [`hertz_profile`],
/// such as a table of it).
pub fn cattaneo_shift_of(profile: impl Fn(f64) -> f64, rho: f64, stick_ratio: f64) -> f64 {
    let s = if stick_ratio.is_finite() {
        stick_ratio.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let stick = if s > 0.0 {
        s * s * profile(rho / s)
    } else {
        0.0
    };
    (profile(rho) - stick).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn validate(pitch_mm: f64, dot_mm: f64) -> Result<MarkerGrid, ConfigError> {
        RawMarkers { pitch_mm, dot_mm }.validate(
            &FieldCheck::new("layout.toml"),
            "sensors[0].markers",
            [320, 240],
            0.0625,
        )
    }

    #[test]
    fn a_grid_that_fits_the_pad_is_taken_and_one_that_does_not_names_its_field() {
        assert_eq!(
            validate(1.2, 0.45).ok(),
            Some(MarkerGrid {
                pitch_mm: 1.2,
                dot_mm: 0.45
            })
        );
        for (pitch, dot, field) in [
            (6.0, 0.5, "sensors[0].markers.pitch_mm"), // 2.5 across a 15 mm pad
            (0.2, 0.1, "sensors[0].markers.pitch_mm"), // dots cannot be seen apart
            (1.2, 0.1, "sensors[0].markers.dot_mm"),   // 1.6 px: unresolved
            (1.2, 0.9, "sensors[0].markers.dot_mm"),   // 75% of the pitch
            (f64::NAN, 0.4, "sensors[0].markers.pitch_mm"),
        ] {
            let e = validate(pitch, dot).expect_err("refused").to_string();
            assert!(e.contains(field), "{pitch} {dot}: {e}");
        }
    }
}
