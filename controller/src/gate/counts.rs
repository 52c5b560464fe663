//! Drop and rejection reasons, and counters with every key always present.

use serde::Serialize;

/// Why frames were dropped or a set was rejected (the `drops` / `sets_rejected` keys).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reason {
    /// Arrived after its set closed, or the set's age exceeded `max_age`.
    Late,
    /// The set never got a frame from every sensor.
    Incomplete,
    /// The set's capture spread exceeded `max_spread`.
    OutOfWindow,
    /// A frame failed its checks (the set then lacks that sensor).
    Corrupt,
    /// A second frame from one sensor for one trigger.
    Duplicate,
    /// A sensor stopped answering.
    Disconnected,
    /// Policy `latest`: a frame replaced by a newer one of its sensor before it was fused.
    Superseded,
    /// A sensor excluded from the sets after it kept failing the window (issue 28 item 3);
    /// not yet produced by any gate.
    Excluded,
}

impl Reason {
    /// All reasons, in the JSON key order.
    pub const ALL: [Reason; 8] = [
        Reason::Late,
        Reason::Incomplete,
        Reason::OutOfWindow,
        Reason::Corrupt,
        Reason::Duplicate,
        Reason::Disconnected,
        Reason::Superseded,
        Reason::Excluded,
    ];

    /// The JSON key.
    pub fn key(self) -> &'static str {
        match self {
            Reason::Late => "late",
            Reason::Incomplete => "incomplete",
            Reason::OutOfWindow => "out_of_window",
            Reason::Corrupt => "corrupt",
            Reason::Duplicate => "duplicate",
            Reason::Disconnected => "disconnected",
            Reason::Superseded => "superseded",
            Reason::Excluded => "excluded",
        }
    }
}

/// A counter per [`Reason`]; serializes with every key present.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ReasonCounts {
    /// See [`Reason::Late`].
    pub late: u64,
    /// See [`Reason::Incomplete`].
    pub incomplete: u64,
    /// See [`Reason::OutOfWindow`].
    pub out_of_window: u64,
    /// See [`Reason::Corrupt`].
    pub corrupt: u64,
    /// See [`Reason::Duplicate`].
    pub duplicate: u64,
    /// See [`Reason::Disconnected`].
    pub disconnected: u64,
    /// See [`Reason::Superseded`].
    pub superseded: u64,
    /// See [`Reason::Excluded`].
    pub excluded: u64,
}

impl ReasonCounts {
    fn slot(&mut self, reason: Reason) -> &mut u64 {
        match reason {
            Reason::Late => &mut self.late,
            Reason::Incomplete => &mut self.incomplete,
            Reason::OutOfWindow => &mut self.out_of_window,
            Reason::Corrupt => &mut self.corrupt,
            Reason::Duplicate => &mut self.duplicate,
            Reason::Disconnected => &mut self.disconnected,
            Reason::Superseded => &mut self.superseded,
            Reason::Excluded => &mut self.excluded,
        }
    }

    /// Add `n` under `reason`.
    pub fn add(&mut self, reason: Reason, n: u64) {
        *self.slot(reason) += n;
    }

    /// The count under `reason`.
    pub fn get(&self, reason: Reason) -> u64 {
        let mut copy = *self;
        *copy.slot(reason)
    }

    /// Sum over all reasons.
    pub fn total(&self) -> u64 {
        Reason::ALL.iter().map(|r| self.get(*r)).sum()
    }
}
