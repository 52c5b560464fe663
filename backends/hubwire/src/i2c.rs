//! The capture-trigger transfer on the I2C bus, written out phase by phase.
//!
//! The bus model derives trigger timing from these phases instead of assuming a constant. At a
//! bus clock `f`, one bit takes `1/f` (2.5 µs at 400 kHz Fast-mode). The phases and their
//! Fast-mode minimum durations (NXP UM10204, table 10) are:
//!
//! | phase | duration |
//! |---|---|
//! | START hold (tHD;STA) | 0.6 µs |
//! | each data/address bit | 1 bit time |
//! | ACK bit | 1 bit time |
//! | STOP set-up (tSU;STO) | 0.6 µs |
//! | bus free before the next START (tBUF) | 1.3 µs |
//!
//! **Sequential trigger** (one board): START, the 7-bit trigger address and W (8 bits), the
//! board's ACK, STOP, bus free. The board captures when it drives its ACK, i.e. after START
//! and 8 bits. At 400 kHz the transfer takes 25.0 µs and capture happens at 20.6 µs, so board
//! `k` (0-based) captures `k × 25.0 µs` after board 0: the sequential spread is
//! `(N − 1) × 25 µs`, within the paper's bound of 30·N µs.
//!
//! **Broadcast trigger**: START, general-call address 0x00 and W, ACK, the command byte
//! [`crate::regs::GENERAL_CALL_CAPTURE`], ACK, STOP, bus free: 47.5 µs at 400 kHz. Every board
//! captures at the ACK of the command byte (43.1 µs), so the transfer adds no spread.

/// Fast-mode START hold time tHD;STA in nanoseconds.
pub const T_HD_STA_NS: u64 = 600;
/// Fast-mode STOP set-up time tSU;STO in nanoseconds.
pub const T_SU_STO_NS: u64 = 600;
/// Fast-mode bus free time tBUF in nanoseconds.
pub const T_BUF_NS: u64 = 1300;
/// The paper's Fast-mode I2C clock.
pub const FAST_MODE_HZ: u32 = 400_000;

/// How the capture trigger reaches the boards.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TriggerMode {
    /// One address-only transfer per board, one after the other.
    Sequential,
    /// One general-call transfer that every board hears at once.
    Broadcast,
}

/// One phase of an I2C transfer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// START condition hold.
    Start,
    /// One bit driven by the controller (address, R/W or data).
    Bit(bool),
    /// The acknowledge bit driven by the target(s); `capture` marks the capture instant.
    Ack {
        /// Boards capture when they drive this ACK.
        capture: bool,
    },
    /// STOP condition set-up.
    Stop,
    /// Bus free time before the next START.
    BusFree,
}

impl Phase {
    /// Duration of the phase in nanoseconds at `bus_hz`.
    pub fn duration_ns(self, bus_hz: u32) -> u64 {
        let bit_ns = 1_000_000_000 / u64::from(bus_hz.max(1));
        match self {
            Phase::Start => T_HD_STA_NS,
            Phase::Bit(_) | Phase::Ack { .. } => bit_ns,
            Phase::Stop => T_SU_STO_NS,
            Phase::BusFree => T_BUF_NS,
        }
    }
}

fn push_byte(phases: &mut Vec<Phase>, byte: u8) {
    for i in (0..8).rev() {
        phases.push(Phase::Bit(byte >> i & 1 == 1));
    }
}

/// The phases of one sequential trigger to the board with 7-bit trigger address `address`.
pub fn sequential_trigger_phases(address: u8) -> Vec<Phase> {
    let mut phases = vec![Phase::Start];
    push_byte(&mut phases, address << 1); // R/W = 0 (write)
    phases.push(Phase::Ack { capture: true });
    phases.extend([Phase::Stop, Phase::BusFree]);
    phases
}

/// The phases of one broadcast (general-call) trigger.
pub fn broadcast_trigger_phases() -> Vec<Phase> {
    let mut phases = vec![Phase::Start];
    push_byte(&mut phases, crate::regs::GENERAL_CALL_ADDR << 1);
    phases.push(Phase::Ack { capture: false });
    push_byte(&mut phases, crate::regs::GENERAL_CALL_CAPTURE);
    phases.push(Phase::Ack { capture: true });
    phases.extend([Phase::Stop, Phase::BusFree]);
    phases
}

/// Timing of one trigger transfer, derived from its phases.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TransferTiming {
    /// From START to the end of bus-free time, in nanoseconds.
    pub total_ns: u64,
    /// From START to the start of the capturing ACK, in nanoseconds.
    pub capture_at_ns: u64,
}

/// Timing of the transfer `phases` at `bus_hz`.
pub fn transfer_timing(phases: &[Phase], bus_hz: u32) -> TransferTiming {
    let mut elapsed = 0;
    let mut capture_at_ns = 0;
    for phase in phases {
        if let Phase::Ack { capture: true } = phase {
            capture_at_ns = elapsed;
        }
        elapsed += phase.duration_ns(bus_hz);
    }
    TransferTiming {
        total_ns: elapsed,
        capture_at_ns,
    }
}

/// Capture instant of each of `boards` boards, in nanoseconds after the first START.
pub fn capture_instants_ns(mode: TriggerMode, boards: u8, bus_hz: u32) -> Vec<u64> {
    match mode {
        TriggerMode::Broadcast => {
            let t = transfer_timing(&broadcast_trigger_phases(), bus_hz);
            vec![t.capture_at_ns; usize::from(boards)]
        }
        TriggerMode::Sequential => {
            let mut start = 0;
            (0..boards)
                .map(|b| {
                    let address = crate::regs::TRIGGER_ADDR_BASE + b;
                    let t = transfer_timing(&sequential_trigger_phases(address), bus_hz);
                    let at = start + t.capture_at_ns;
                    start += t.total_ns;
                    at
                })
                .collect()
        }
    }
}

/// Total bus time of triggering `boards` boards, in nanoseconds.
pub fn trigger_bus_time_ns(mode: TriggerMode, boards: u8, bus_hz: u32) -> u64 {
    match mode {
        TriggerMode::Broadcast => transfer_timing(&broadcast_trigger_phases(), bus_hz).total_ns,
        TriggerMode::Sequential => (0..boards)
            .map(|b| {
                let address = crate::regs::TRIGGER_ADDR_BASE + b;
                transfer_timing(&sequential_trigger_phases(address), bus_hz).total_ns
            })
            .sum(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sequential_transfer_is_25_us_and_captures_at_ack() {
        let t = transfer_timing(&sequential_trigger_phases(0x40), FAST_MODE_HZ);
        assert_eq!(t.total_ns, 25_000);
        assert_eq!(t.capture_at_ns, 20_600);
    }

    #[test]
    fn broadcast_transfer_is_47_5_us() {
        let t = transfer_timing(&broadcast_trigger_phases(), FAST_MODE_HZ);
        assert_eq!(t.total_ns, 47_500);
        assert_eq!(t.capture_at_ns, 43_100);
    }

    #[test]
    fn address_bits_are_msb_first_with_write_bit() {
        let phases = sequential_trigger_phases(0x41);
        let bits: Vec<bool> = phases
            .iter()
            .filter_map(|p| match p {
                Phase::Bit(b) => Some(*b),
                _ => None,
            })
            .collect();
        // 0x41 << 1 = 0b1000_0010
        assert_eq!(bits, [true, false, false, false, false, false, true, false]);
    }

    #[test]
    fn sequential_spread_is_within_paper_bound() {
        for n in 1..=32u8 {
            let at = capture_instants_ns(TriggerMode::Sequential, n, FAST_MODE_HZ);
            let spread = at.last().copied().unwrap_or(0) - at.first().copied().unwrap_or(0);
            assert!(spread <= 30_000 * u64::from(n), "n={n} spread={spread}");
        }
        let b = capture_instants_ns(TriggerMode::Broadcast, 7, FAST_MODE_HZ);
        assert!(b.iter().all(|&t| t == b[0]));
    }
}
