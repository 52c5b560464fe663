//! The `[grasp]` section's settings: how a grasp whose target is `auto` finds its own force,
//! and how the slip reflex keeps a held object (`docs/control.md`, "Slip reflex";
//! `docs/config.md`, `[grasp]`). Forces are per finger, as a request's `target_force_n` is.

/// How a grasp finds and keeps its force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GraspSettings {
    /// The light first grip of an `auto` grasp, N per finger.
    pub preload_n: f64,
    /// The most an `auto` grasp or the reflex may ask of a finger, N.
    pub max_force_n: f64,
    /// How far above the least force that holds a grasp settles: the share added to the
    /// force that the contacts' measured slip says would just hold (1.5: 150% more, so
    /// that the grip holds through a load that doubles before the reflex can follow,
    /// with the detector's reading high at a grip that holds; `docs/control.md`, "The
    /// margin").
    pub slip_margin: f64,
    /// The slip reflex while holding (on by default).
    pub reflex: bool,
    /// The fastest the reflex raises a finger's target, N/s; it relaxes a tenth as fast
    /// ([`RELAX_SHARE`]).
    pub reflex_rate_n_s: f64,
}

/// A held grasp relaxes toward the least force that holds at this share of the reflex's
/// rate: slowly, so that a load that stays is followed without a sawtooth.
pub const RELAX_SHARE: f64 = 0.1;

impl Default for GraspSettings {
    fn default() -> Self {
        Self {
            preload_n: 0.3,
            max_force_n: 4.0,
            slip_margin: 1.5,
            reflex: true,
            reflex_rate_n_s: 4.0,
        }
    }
}
