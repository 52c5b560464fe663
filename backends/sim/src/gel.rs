//! The gel's mechanics under a ball, as a real GelSight gel shows them (the realistic
//! simulator, docs/calibration.md "Realistic optics").
//!
//! A real gel does not stop at the ball's rim: its skin is held in tension over the soft
//! elastomer, so the press spreads into a smooth skirt around the contact. That is a
//! membrane on an elastic (Winkler) foundation: outside the contact the surface obeys
//! `ℓ² ∇²u = u`, whose decaying radial solution is `u(r) = A·K₀(r/ℓ)` (modified Bessel
//! function of the second kind), with ℓ the skirt's length. Where the gel touches the ball
//! it has the ball's shape; at the contact's edge the skin leaves the ball tangentially
//! (depth and slope continuous), which fixes A and how much deeper the whole press sits
//! than the cap inside the contact.
//!
//! [`BallOnGel`] is that profile: the cap of contact radius a, exactly the ball's (its
//! depth relative to the contact's edge is the geometric cap `R − sqrt(R² − a²)`, as a
//! press's labels have it), lowered by the skirt's depth at the edge, and the skirt
//! outside. ℓ = 0 is the sharp-rimmed press of [`crate::scene::HeightMap::ball_press`].

use crate::scene::HeightMap;

/// The deepest contact, as a share of the ball's radius (the rim's slope is finite).
const MAX_CONTACT_SHARE: f64 = 0.999;
/// The skirt is drawn out to where it is this share of its depth at the contact's edge.
const SKIRT_CUTOFF: f64 = 1e-4;

/// A ball pressed into a gel with a skirt: radial depth and slope, in the units of its
/// lengths (px or mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallOnGel {
    /// Ball radius.
    pub ball_radius: f64,
    /// Contact radius (where the gel leaves the ball).
    pub contact_radius: f64,
    /// The skirt's length ℓ (0: no skirt).
    pub skirt_length: f64,
    /// Depth of the skirt at the contact's edge.
    pub edge_depth: f64,
    /// K₀(a/ℓ), the skirt's normaliser.
    k0_edge: f64,
}

impl BallOnGel {
    /// A ball of `ball_radius` touching the gel over `contact_radius`, skirt `skirt_length`
    /// (same units). Non-finite or negative inputs count as 0; the contact is kept below
    /// the ball's radius.
    pub fn new(ball_radius: f64, contact_radius: f64, skirt_length: f64) -> Self {
        let finite = |v: f64| if v.is_finite() { v.max(0.0) } else { 0.0 };
        let r = finite(ball_radius);
        let a = finite(contact_radius).min(r * MAX_CONTACT_SHARE);
        let l = finite(skirt_length);
        let (mut edge_depth, mut k0_edge) = (0.0, 1.0);
        if l > 0.0 && a > 0.0 {
            let (k0, k1) = bessel_k01(a / l);
            let slope = a / (r * r - a * a).sqrt();
            if k0 > 0.0 && k1 > 0.0 {
                edge_depth = slope * l * k0 / k1;
                k0_edge = k0;
            }
        }
        Self {
            ball_radius: r,
            contact_radius: a,
            skirt_length: l,
            edge_depth,
            k0_edge,
        }
    }

    /// The cap's depth inside the contact, relative to its edge.
    pub fn cap_depth(&self) -> f64 {
        let (r, a) = (self.ball_radius, self.contact_radius);
        r - (r * r - a * a).sqrt()
    }

    /// Depth into the gel at distance `rho` from the centre, and its slope d(depth)/dρ
    /// (negative: shallower outwards).
    pub fn at(&self, rho: f64) -> (f64, f64) {
        let (r, a, l) = (self.ball_radius, self.contact_radius, self.skirt_length);
        let rho = if rho.is_finite() { rho.abs() } else { f64::MAX };
        if rho < a {
            let s = (r * r - rho * rho).sqrt();
            return (s - (r - self.cap_depth()) + self.edge_depth, -rho / s);
        }
        if l <= 0.0 || self.edge_depth <= 0.0 {
            return (0.0, 0.0);
        }
        let (k0, k1) = bessel_k01(rho / l);
        let scale = self.edge_depth / self.k0_edge;
        (scale * k0, -scale * k1 / l)
    }

    /// How far from the centre the press reaches (the skirt down to `SKIRT_CUTOFF` (10⁻⁴) of its
    /// edge depth).
    pub fn reach(&self) -> f64 {
        let (a, l) = (self.contact_radius, self.skirt_length);
        if l <= 0.0 || self.edge_depth <= 0.0 {
            return a;
        }
        // K₀(z) falls at least as fast as e^{−z} beyond the edge.
        a + l * (1.0 / SKIRT_CUTOFF).ln()
    }

    /// The height map (depth into the gel, mm) of this press (lengths in mm) centred at
    /// (`cx_px`, `cy_px`) on a `width_px × height_px` pad of `mm_per_px` pixels.
    pub fn height_map(
        &self,
        (width_px, height_px): (usize, usize),
        mm_per_px: f64,
        (cx_px, cy_px): (f64, f64),
    ) -> HeightMap {
        let mut map = HeightMap::flat(width_px, height_px);
        if mm_per_px.is_nan() || mm_per_px <= 0.0 || mm_per_px.is_infinite() {
            return map;
        }
        let reach = self.reach();
        let floor = SKIRT_CUTOFF * self.edge_depth;
        for y in 0..height_px {
            for x in 0..width_px {
                let rho = (x as f64 - cx_px).hypot(y as f64 - cy_px) * mm_per_px;
                if rho >= reach {
                    continue;
                }
                let (d, _) = self.at(rho);
                if d > floor && d.is_finite() {
                    map.depth_mm[y * width_px + x] = d as f32;
                }
            }
        }
        map
    }
}

/// The modified Bessel functions of the second kind K₀(z) and K₁(z), z > 0, from their
/// integrals `K_ν(z) = ∫₀^∞ exp(−z cosh t) cosh(νt) dt` (Simpson's rule up to where the
/// integrand is e⁻⁴⁰ of its start). (∞, ∞) at z ≤ 0, (0, 0) for huge z; never NaN.
pub fn bessel_k01(z: f64) -> (f64, f64) {
    if z.is_nan() || z <= 0.0 {
        return (f64::INFINITY, f64::INFINITY);
    }
    if z > 700.0 {
        return (0.0, 0.0);
    }
    let end = (1.0 + 40.0 / z).acosh();
    let n = 128;
    let h = end / n as f64;
    let (mut k0, mut k1) = (0.0, 0.0);
    for i in 0..=n {
        let t = i as f64 * h;
        let w = if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        let c = t.cosh();
        // Scaled by e^{z} so large z keeps its precision; undone below.
        let e = (-z * (c - 1.0)).exp();
        k0 += w * e;
        k1 += w * e * c;
    }
    let scale = h / 3.0 * (-z).exp();
    (k0 * scale, k1 * scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bessel_values_match_the_tables() {
        // Abramowitz & Stegun, table 9.8: K₀(1) = 0.4210, K₁(1) = 0.6019, K₀(0.1) = 2.4271,
        // K₁(0.1) = 9.8538, K₀(5) = 3.6911e-3, K₁(5) = 4.0446e-3.
        for (z, k0, k1) in [
            (1.0, 0.421_024, 0.601_907),
            (0.1, 2.427_069, 9.853_845),
            (5.0, 3.691_1e-3, 4.044_6e-3),
        ] {
            let (a, b) = bessel_k01(z);
            assert!((a / k0 - 1.0).abs() < 1e-3, "K0({z}) = {a}");
            assert!((b / k1 - 1.0).abs() < 1e-3, "K1({z}) = {b}");
        }
        for z in [0.0, -1.0, f64::NAN, 1e-300, 1e6, f64::INFINITY] {
            let (a, b) = bessel_k01(z);
            assert!(!a.is_nan() && !b.is_nan(), "{z}: {a} {b}");
        }
    }

    #[test]
    fn the_skirt_leaves_the_ball_tangentially_and_the_cap_is_the_balls() {
        let p = BallOnGel::new(2.0, 1.2, 0.5);
        let a = 1.2;
        let (inside, s_in) = p.at(a - 1e-9);
        let (outside, s_out) = p.at(a + 1e-9);
        assert!((inside - outside).abs() < 1e-6, "{inside} {outside}");
        assert!((s_in - s_out).abs() < 1e-4, "{s_in} {s_out}");
        // The cap relative to the edge is the ball's.
        let (centre, _) = p.at(0.0);
        assert!((centre - p.edge_depth - p.cap_depth()).abs() < 1e-12);
        assert!((p.cap_depth() - (2.0 - (4.0f64 - 1.44).sqrt())).abs() < 1e-12);
        // The skirt decays.
        assert!(p.at(a + 2.0).0 < 0.1 * outside);
        // No skirt: the sharp press.
        let sharp = BallOnGel::new(2.0, 1.2, 0.0);
        assert_eq!(sharp.at(1.3), (0.0, 0.0));
        assert_eq!(sharp.edge_depth, 0.0);
    }

    #[test]
    fn extremes_stay_finite() {
        for (r, a, l) in [
            (2.0, 5.0, 0.5),
            (2.0, 2.0, 1e-9),
            (f64::INFINITY, 1.0, 0.5),
            (2.0, f64::NAN, 0.5),
            (0.0, 0.0, 0.0),
            (2.0, 1.0, 1e9),
        ] {
            let p = BallOnGel::new(r, a, l);
            for rho in [0.0, 0.5, 1.0, 3.0, f64::INFINITY, f64::NAN] {
                let (d, s) = p.at(rho);
                assert!(
                    d.is_finite() && s.is_finite(),
                    "{r} {a} {l} @{rho}: {d} {s}"
                );
            }
            let map = p.height_map((16, 12), 0.25, (8.0, 6.0));
            assert!(map.depth_mm.iter().all(|d| d.is_finite() && *d >= 0.0));
        }
    }

    #[test]
    fn the_height_map_has_the_contact_and_the_skirt() {
        let p = BallOnGel::new(2.0, 1.0, 0.3);
        let map = p.height_map((64, 64), 0.0625, (32.0, 32.0));
        let centre = f64::from(map.depth_mm[32 * 64 + 32]);
        assert!((centre - p.at(0.0).0).abs() < 1e-5);
        // 1.25 mm from the centre (outside the contact): skirt, shallower than the edge.
        let skirt = f64::from(map.depth_mm[32 * 64 + 52]);
        assert!(skirt > 0.0 && skirt < p.edge_depth, "{skirt}");
    }
}
