//! Realistic optics (`[hub.sim] optics = "realistic"`): a gel lit and filmed the way a real
//! GelSight Mini is, with parameters fitted to its data (`../shared/data/gelsight-mini-presses`,
//! `optics::fit`, docs/calibration.md).
//!
//! Per pixel at normalised position (u, v) = (x/W − ½, y/H − ½) with surface gradient g and
//! normal n ∝ (gx, gy, 1):
//!
//! - **LED falloff across the pad**: the flat gel's colour `B_c(u, v)` is a cubic polynomial
//!   per channel fitted to the real background (its channel means and its falloff towards
//!   the edges and corners), taken to linear light by the camera gamma: `E_c = 255 (B_c/255)^γ`;
//! - **non-Lambertian reflectance**: LED k (azimuth φ_k, elevation e) lights a facet with
//!   `a_k + V(g) (max(0, n·L_k) + k_s max(0, n·H_k)^p)`, normalised so a flat facet gives 1:
//!   a diffuse term, a specular lobe around the half vector H_k between the LED and the
//!   camera, and an ambient share a_k per LED;
//!   The diffuse term wraps a little past the terminator (`wrap`), as light scattered in a
//!   translucent gel does;
//! - **shadowing at steep slopes**: `V(g) = 1 / (1 + (|g|/g_s)²)`, the share of the LEDs'
//!   direct light that reaches a facet as steep as |g| (masked by the dent's rim);
//! - **colour crosstalk**: channel c sees LED k with weight `M_ck` (`1 − 2x` on the diagonal,
//!   `x` off it), so a red slope also moves green and blue;
//! - **camera gamma and noise**: the linear light `gain_c · E_c · Σ_k M_ck S_k` is encoded
//!   with `1/γ`, the unit's offset added, and Gaussian noise per channel (σ fitted to the
//!   real frames' pixel noise) on top.
//!
//! A flat gel therefore shows exactly the fitted background (times the unit's gain); every
//! value is finite for any finite or infinite slope, and the camera clamps to 0–255.

use crate::unit::UnitVariation;

/// Terms of the background polynomial: 1, u, v, u², uv, v², u³, u²v, uv², v³.
pub const BACKGROUND_TERMS: usize = 10;

/// The background polynomial's basis at (u, v).
pub fn background_basis(u: f64, v: f64) -> [f64; BACKGROUND_TERMS] {
    [
        1.0,
        u,
        v,
        u * u,
        u * v,
        v * v,
        u * u * u,
        u * u * v,
        u * v * v,
        v * v * v,
    ]
}

/// The parameters of the realistic optics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RealisticParams {
    /// The flat gel's colour per channel, grey levels, as coefficients of
    /// [`background_basis`].
    pub background: [[f64; BACKGROUND_TERMS]; 3],
    /// Camera gamma (linear light = encoded^γ).
    pub gamma: f64,
    /// Azimuths of the red, green and blue LEDs, degrees (image x towards y).
    pub led_azimuth_deg: [f64; 3],
    /// LED elevation above the gel plane, degrees.
    pub led_elevation_deg: f64,
    /// Per LED: light reaching a facet whatever its normal, relative to the directional
    /// light (1).
    pub ambient: [f64; 3],
    /// Weight of the specular lobe relative to the diffuse term.
    pub specular: f64,
    /// Exponent of the specular lobe (larger: narrower).
    pub shininess: f64,
    /// Slope |g| at which a facet keeps half of the LEDs' direct light.
    pub shadow_slope: f64,
    /// Wrap of the diffuse term, `max(0, (n·L + w) / (1 + w))`: light scattered in the
    /// translucent gel reaches facets a little past the terminator (0: Lambert's cosine).
    pub wrap: f64,
    /// Share of each other LED's light in a channel (0: none).
    pub crosstalk: f64,
    /// Camera noise per channel, grey levels (Gaussian).
    pub noise_rgb: [f64; 3],
    /// The gel's mechanics, fitted with the optics: the length of the skirt a ball's press
    /// spreads into around its contact, mm ([`crate::gel`]; 0: the gel stops at the
    /// contact's rim).
    pub skirt_mm: f64,
}

/// The parameters fitted to the real GelSight Mini with a sharp-rimmed gel (the presses
/// rendered as the ball's cap and nothing around it, labelled by `calibrate label` for a
/// 3.68 mm ball, `optics::fit::MINI_PRESSES`): the colours' sector means and the response
/// curve a table trained on them reads (`optics::response`; `optics_fit`'s `fit` with
/// `FIT_ELEVATION=25,3`; the side-by-side statistics are in docs/calibration.md).
pub const MINI: RealisticParams = RealisticParams {
    background: MINI_BACKGROUND,
    gamma: 1.716,
    led_azimuth_deg: [88.2, 186.8, 262.6],
    led_elevation_deg: 15.0,
    ambient: [0.0902, 0.3406, 0.3773],
    specular: 0.0053,
    shininess: 10.6,
    shadow_slope: 4.4,
    wrap: 0.05,
    crosstalk: 0.0028,
    noise_rgb: [1.59, 1.07, 1.86],
    skirt_mm: 0.0,
};

/// The parameters fitted to the real GelSight Mini together with the gel's skirt around a
/// contact (`optics = "realistic-gel"`; `optics_fit`'s `fit` with
/// `FIT_START=58,0.5,20,3 FIT_ROUNDS=60`, giving `optics::fit::MINI_GEL_PRESSES`).
pub const MINI_GEL: RealisticParams = RealisticParams {
    background: MINI_BACKGROUND,
    gamma: 2.096,
    led_azimuth_deg: [83.9, 189.0, 260.3],
    led_elevation_deg: 12.44,
    ambient: [0.0148, 0.1640, 0.2773],
    specular: 0.547,
    shininess: 15.3,
    shadow_slope: 1.58,
    wrap: 0.026,
    crosstalk: 0.0,
    noise_rgb: [1.59, 1.07, 1.86],
    // 54 px of the Mini's 0.0317 mm.
    skirt_mm: 1.712,
};

/// The revision of the realistic optics' fitted parameters ([`MINI`], [`MINI_GEL`]): part
/// of a simulated self-calibration's cache key, so a refit never reuses a model calibrated
/// on the old optics. 2: the refit to the Mini's response curve (2026-11-28).
pub const FIT_REVISION: u32 = 2;

/// The real Mini background's polynomial (`optics::fit::fit_background`).
const MINI_BACKGROUND: [[f64; BACKGROUND_TERMS]; 3] = [
    [
        127.355, 13.196, 79.265, -267.154, -1.523, -264.247, -35.707, -150.086, -26.893, -142.459,
    ],
    [
        112.333, 0.338, -12.666, -99.561, -0.698, -58.276, -58.845, 18.555, 6.366, 10.554,
    ],
    [
        142.435, -1.975, -52.746, -167.648, -7.370, -183.931, 2.991, 63.439, 14.395, 97.617,
    ],
];

/// Shading of one camera under [`RealisticParams`]: the per-pixel linear background is
/// computed once.
#[derive(Debug, Clone)]
pub struct RealisticShader {
    params: RealisticParams,
    lights: [[f64; 3]; 3],
    halves: [[f64; 3]; 3],
    /// Flat-facet normaliser per LED.
    flat: [f64; 3],
    /// Linear background light per pixel and channel, unit gain applied.
    linear: Vec<f32>,
    width_px: usize,
    offset: [f64; 3],
}

impl RealisticShader {
    /// The shader of a `width_px × height_px` camera with `unit`'s LED gains and offsets
    /// (its vignetting is part of the fitted falloff).
    pub fn new(
        params: &RealisticParams,
        width_px: usize,
        height_px: usize,
        unit: &UnitVariation,
    ) -> Self {
        let p = *params;
        let el = p.led_elevation_deg.to_radians();
        let lights = p.led_azimuth_deg.map(|az| {
            let az = az.to_radians();
            [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
        });
        let halves = lights.map(|l| normalise([l[0], l[1], l[2] + 1.0]));
        let mut flat = [0.0; 3];
        for k in 0..3 {
            flat[k] = p.ambient[k]
                + wrapped(lights[k][2], p.wrap)
                + p.specular * lobe(halves[k][2], p.shininess);
        }
        let (w, h) = (width_px.max(1), height_px.max(1));
        let mut linear = Vec::with_capacity(w * h * 3);
        for y in 0..height_px {
            for x in 0..width_px {
                let b = background_rgb(&p, x, y, w, h);
                for (gain, b) in unit.led_gain.iter().zip(b) {
                    linear.push((gain.max(0.0) * to_linear(b, p.gamma)) as f32);
                }
            }
        }
        Self {
            params: p,
            lights,
            halves,
            flat,
            linear,
            width_px,
            offset: unit.offset,
        }
    }

    /// The camera's encoded RGB (before noise and clamping) of the facet with gradient
    /// (`gx`, `gy`) at pixel (`x`, `y`).
    pub fn shade(&self, x: usize, y: usize, gx: f64, gy: f64) -> [f64; 3] {
        self.shade_covered(x, y, (gx, gy), 1.0)
    }

    /// The encoded RGB of pixel (`x`, `y`) whose footprint is `coverage` (0–1) a facet
    /// with gradient (`gx`, `gy`) and the rest flat gel: the two lights mixed in linear
    /// light, as the sensor adds them, then encoded.
    pub fn shade_covered(
        &self,
        x: usize,
        y: usize,
        (gx, gy): (f64, f64),
        coverage: f64,
    ) -> [f64; 3] {
        let p = &self.params;
        let f = if coverage.is_finite() {
            coverage.clamp(0.0, 1.0)
        } else {
            1.0
        };
        let s = self.relative_light(gx, gy);
        let at = (y * self.width_px + x) * 3;
        let x_talk = p.crosstalk.clamp(0.0, 0.5);
        [0, 1, 2].map(|c| {
            let mix: f64 = s
                .iter()
                .enumerate()
                .map(|(k, s)| if k == c { 1.0 - 2.0 * x_talk } else { x_talk } * s)
                .sum();
            // A flat facet's light is 1 for every LED, so 1 after the crosstalk too.
            let mix = f * mix + (1.0 - f);
            let lin = f64::from(self.linear.get(at + c).copied().unwrap_or(0.0)) * mix;
            to_encoded(lin, p.gamma) + self.offset[c]
        })
    }

    /// Each LED's light on the facet with gradient (`gx`, `gy`), relative to a flat one's.
    fn relative_light(&self, gx: f64, gy: f64) -> [f64; 3] {
        let p = &self.params;
        let (gx, gy) = if gx.is_finite() && gy.is_finite() {
            (gx, gy)
        } else {
            // An infinite slope is a vertical wall: no direct light reaches it.
            (0.0, 1e9)
        };
        let slope = gx.hypot(gy);
        let n = normalise([gx, gy, 1.0]);
        let reach = 1.0 / (1.0 + (slope / p.shadow_slope.max(1e-6)).powi(2));
        [0, 1, 2].map(|k| {
            let diffuse = wrapped(dot(n, self.lights[k]), p.wrap);
            let specular = p.specular * lobe(dot(n, self.halves[k]), p.shininess);
            (p.ambient[k] + reach * (diffuse + specular)) / self.flat[k]
        })
    }

    /// Camera noise per channel, grey levels.
    pub fn noise_rgb(&self) -> [f64; 3] {
        self.params.noise_rgb
    }
}

/// The fitted flat-gel colour at pixel (`x`, `y`) of a `w × h` image, grey levels.
pub fn background_rgb(p: &RealisticParams, x: usize, y: usize, w: usize, h: usize) -> [f64; 3] {
    let u = (x as f64 + 0.5) / w as f64 - 0.5;
    let v = (y as f64 + 0.5) / h as f64 - 0.5;
    let basis = background_basis(u, v);
    p.background
        .map(|coef| coef.iter().zip(&basis).map(|(a, b)| a * b).sum::<f64>())
}

fn wrapped(cos: f64, wrap: f64) -> f64 {
    let w = wrap.clamp(0.0, 1.0);
    ((cos + w) / (1.0 + w)).max(0.0)
}

fn lobe(cos: f64, shininess: f64) -> f64 {
    cos.max(0.0).powf(shininess.max(1.0))
}

/// Encoded grey level → linear light (0–255 scale).
fn to_linear(encoded: f64, gamma: f64) -> f64 {
    255.0 * (encoded.clamp(0.0, 255.0) / 255.0).powf(gamma.max(0.1))
}

/// Linear light → encoded grey level (not clamped above: the camera saturates later).
fn to_encoded(linear: f64, gamma: f64) -> f64 {
    255.0 * (linear.max(0.0) / 255.0).powf(1.0 / gamma.max(0.1))
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalise(v: [f64; 3]) -> [f64; 3] {
    let n = dot(v, v).sqrt();
    if n > 0.0 && n.is_finite() {
        v.map(|c| c / n)
    } else {
        [0.0, 0.0, 1.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNIT: UnitVariation = UnitVariation::NEUTRAL;

    #[test]
    fn a_flat_facet_shows_the_fitted_background() {
        let s = RealisticShader::new(&MINI, 64, 48, &UNIT);
        for (x, y) in [(0, 0), (32, 24), (63, 47), (10, 40)] {
            let want = background_rgb(&MINI, x, y, 64, 48);
            let got = s.shade(x, y, 0.0, 0.0);
            for c in 0..3 {
                assert!(
                    (got[c] - want[c].clamp(0.0, 255.0)).abs() < 0.01,
                    "{x},{y}: {got:?} {want:?}"
                );
            }
        }
    }

    #[test]
    fn a_slope_towards_an_led_brightens_its_channel_and_steep_walls_darken() {
        let s = RealisticShader::new(&MINI, 64, 48, &UNIT);
        let flat = s.shade(32, 24, 0.0, 0.0);
        let az = MINI.led_azimuth_deg[0].to_radians();
        let towards = s.shade(32, 24, 0.3 * az.cos(), 0.3 * az.sin());
        assert!(towards[0] > flat[0] + 5.0, "{towards:?} {flat:?}");
        let away = s.shade(32, 24, -0.3 * az.cos(), -0.3 * az.sin());
        assert!(away[0] < flat[0] - 5.0, "{away:?} {flat:?}");
        let wall = s.shade(32, 24, 50.0 * az.cos(), 50.0 * az.sin());
        assert!(wall.iter().zip(&flat).all(|(w, f)| w < f), "{wall:?}");
    }

    #[test]
    fn extremes_stay_finite() {
        let s = RealisticShader::new(&MINI, 8, 6, &UNIT);
        for (gx, gy) in [
            (f64::INFINITY, 0.0),
            (f64::NAN, 1.0),
            (1e300, -1e300),
            (0.0, f64::NEG_INFINITY),
        ] {
            let v = s.shade(3, 3, gx, gy);
            assert!(v.iter().all(|c| c.is_finite()), "{gx} {gy}: {v:?}");
        }
        let saturating = UnitVariation {
            led_gain: [40.0; 3],
            offset: [300.0; 3],
            vignetting: 0.0,
        };
        let black = UnitVariation {
            led_gain: [0.0; 3],
            offset: [-300.0; 3],
            vignetting: 0.0,
        };
        for unit in [saturating, black] {
            let s = RealisticShader::new(&MINI, 8, 6, &unit);
            let v = s.shade(7, 5, 0.5, -0.5);
            assert!(v.iter().all(|c| c.is_finite()), "{v:?}");
        }
    }
}
