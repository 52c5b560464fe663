//! Unit-to-unit variation of the simulated sensors, drawn from the seed.
//!
//! Real boards differ in LED brightness, colour balance and lens shading; the calibration
//! issue's zero-shot transfer exists because of it. Each sensor gets its own draw.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

/// One sensor unit's optical peculiarities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitVariation {
    /// Per-channel LED gain (about 1).
    pub led_gain: [f64; 3],
    /// Per-channel offset in grey levels.
    pub offset: [f64; 3],
    /// Brightness loss at the image corner (0 = none).
    pub vignetting: f64,
}

/// A seeded generator for stream `stream` of `seed` (streams do not overlap in practice).
pub fn rng_for(seed: u64, stream: u64) -> Pcg64Mcg {
    // SplitMix64 finaliser spreads nearby seeds over the state space.
    let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    Pcg64Mcg::seed_from_u64(z ^ (z >> 31))
}

impl UnitVariation {
    /// A unit without peculiarities: gain 1, no offset, no vignetting.
    pub const NEUTRAL: Self = Self {
        led_gain: [1.0; 3],
        offset: [0.0; 3],
        vignetting: 0.0,
    };

    /// The variation of sensor `index` under `seed`.
    pub fn draw(seed: u64, index: usize) -> Self {
        let mut rng = rng_for(seed, 0x1000 + index as u64);
        let mut gain = || rng.random_range(0.85..1.15);
        let led_gain = [gain(), gain(), gain()];
        let mut off = || rng.random_range(-8.0..8.0);
        let offset = [off(), off(), off()];
        Self {
            led_gain,
            offset,
            vignetting: rng.random_range(0.15..0.35),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_differ_but_are_reproducible() {
        let a = UnitVariation::draw(1, 0);
        assert_eq!(a, UnitVariation::draw(1, 0));
        assert_ne!(a, UnitVariation::draw(1, 1));
        assert_ne!(a, UnitVariation::draw(2, 0));
        assert!(a.led_gain.iter().all(|g| (0.85..1.15).contains(g)));
    }
}
