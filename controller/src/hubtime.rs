//! Hub time: wrap-safe arithmetic on the hub's u32 microsecond counter and u32 sequences.
//!
//! The counter wraps every 2^32 µs (71.6 minutes). Differences are taken in two's complement,
//! so any two stamps less than 35.8 minutes apart compare correctly across the wrap.

/// `a − b` for two u32 stamps, as a signed difference.
pub fn signed_diff(a: u32, b: u32) -> i64 {
    i64::from(a.wrapping_sub(b) as i32)
}

/// `a` is newer than `b` in serial-number arithmetic.
pub fn seq_newer(a: u32, b: u32) -> bool {
    signed_diff(a, b) > 0
}

/// Maps hub u32 microsecond stamps to host u64 microseconds through one known pair.
///
/// The anchor is moved forward with [`HubTimeMap::reanchor`] at least once per half wrap
/// (every set does), so mapping stays exact across any number of wraps. Clock drift is the
/// transport's job (the CDC clock sync re-anchors with its estimate).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HubTimeMap {
    hub_us: u32,
    host_us: u64,
}

impl HubTimeMap {
    /// A map in which hub time `hub_us` is host time `host_us`.
    pub fn new(hub_us: u32, host_us: u64) -> Self {
        Self { hub_us, host_us }
    }

    /// Host time of hub stamp `hub_us` (saturating at 0).
    pub fn to_host_us(&self, hub_us: u32) -> u64 {
        let host = i128::from(self.host_us) + i128::from(signed_diff(hub_us, self.hub_us));
        u64::try_from(host.max(0)).unwrap_or(u64::MAX)
    }

    /// Move the anchor to a newer hub stamp, keeping the mapping.
    pub fn reanchor(&mut self, hub_us: u32) {
        *self = Self::new(hub_us, self.to_host_us(hub_us));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn maps_across_the_wrap() {
        let mut map = HubTimeMap::new(u32::MAX - 10, 1_000);
        assert_eq!(map.to_host_us(5), 1_016);
        map.reanchor(5);
        assert_eq!(map.to_host_us(u32::MAX), 1_010);
        assert!(seq_newer(0, u32::MAX));
        assert!(!seq_newer(u32::MAX, 0));
    }

    proptest! {
        #[test]
        fn any_offset_maps_the_same(base in any::<u32>(), host in 1_000_000_000u64..2_000_000_000, steps in proptest::collection::vec(0u32..1_000_000_000, 1..20)) {
            let mut map = HubTimeMap::new(base, host);
            let mut hub = base;
            let mut expect = host;
            for s in steps {
                hub = hub.wrapping_add(s);
                expect += u64::from(s);
                prop_assert_eq!(map.to_host_us(hub), expect);
                map.reanchor(hub);
            }
        }
    }
}
