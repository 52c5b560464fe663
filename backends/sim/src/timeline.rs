//! The hub's bus, simulated at the transaction level. Every timestamp comes from here.
//!
//! One set: the coordinator sends the trigger over I2C (its phases are in
//! `gelgrip_hubwire::i2c`); each board captures at the instant it acknowledges, plus its
//! interrupt jitter and any injected capture delay; it buffers the JPEG for `t_buf`; then the
//! coordinator reads the boards over SPI one after another, each read starting when both the
//! bus and that board are ready and lasting the frame's actual length × 8 / f_spi; each frame
//! reaches the host `t_usb` (plus any injected delivery delay) after its read ends. The next
//! set's trigger starts when the SPI bus is free.

use gelgrip_hubwire::i2c::{self, TriggerMode};

/// Bus parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BusParams {
    /// Trigger mode.
    pub trigger: TriggerMode,
    /// I2C clock, Hz.
    pub i2c_hz: u32,
    /// SPI clock, Hz.
    pub spi_clock_hz: u32,
    /// Board buffering time, ns.
    pub t_buf_ns: u64,
    /// Forwarding time to the host, ns.
    pub t_usb_ns: u64,
}

/// What one board contributes to a set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardInput {
    /// Jitter drawn for this capture (interrupt jitter plus any injected jitter), ns.
    pub jitter_ns: u64,
    /// Injected capture delay, ns.
    pub capture_delay_ns: u64,
    /// Injected delivery delay, ns.
    pub delivery_delay_ns: u64,
    /// Bytes to read over SPI, or `None` if the frame was lost.
    pub frame_bytes: Option<usize>,
}

/// When things happened to one board, in host ns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardTimes {
    /// The board acknowledged its trigger.
    pub trigger_receipt_ns: u64,
    /// The capture instant.
    pub capture_ns: u64,
    /// The SPI read ended (`None` if the frame was lost).
    pub read_end_ns: Option<u64>,
    /// The frame reached the host.
    pub delivered_ns: Option<u64>,
}

/// The timeline of one set.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SetTimes {
    /// Per board, in board order.
    pub boards: Vec<BoardTimes>,
    /// The SPI bus is free for the next set.
    pub bus_free_ns: u64,
    /// The hub's set-end notice reaches the host.
    pub set_end_ns: u64,
}

/// SPI time of `bytes` bytes at `hz`, ns.
pub fn spi_time_ns(bytes: usize, hz: u32) -> u64 {
    (bytes as u64 * 8 * 1_000_000_000).div_ceil(u64::from(hz.max(1)))
}

/// Schedule one set whose trigger starts at `start_ns`.
pub fn schedule_set(params: &BusParams, start_ns: u64, boards: &[BoardInput]) -> SetTimes {
    let n = u8::try_from(boards.len()).unwrap_or(u8::MAX);
    let receipts = i2c::capture_instants_ns(params.trigger, n, params.i2c_hz);
    let trigger_end = start_ns + i2c::trigger_bus_time_ns(params.trigger, n, params.i2c_hz);
    let mut bus_ns = start_ns + receipts.first().copied().unwrap_or(0);
    let mut out = Vec::with_capacity(boards.len());
    for (b, receipt) in boards.iter().zip(receipts) {
        let trigger_receipt_ns = start_ns + receipt;
        let capture_ns = trigger_receipt_ns + b.jitter_ns + b.capture_delay_ns;
        let (read_end_ns, delivered_ns) = match b.frame_bytes {
            Some(bytes) => {
                let ready = capture_ns + params.t_buf_ns;
                let end = bus_ns.max(ready) + spi_time_ns(bytes, params.spi_clock_hz);
                bus_ns = end;
                (Some(end), Some(end + params.t_usb_ns + b.delivery_delay_ns))
            }
            None => (None, None),
        };
        out.push(BoardTimes {
            trigger_receipt_ns,
            capture_ns,
            read_end_ns,
            delivered_ns,
        });
    }
    let bus_free_ns = bus_ns.max(trigger_end);
    SetTimes {
        boards: out,
        bus_free_ns,
        set_end_ns: bus_free_ns + params.t_usb_ns,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(trigger: TriggerMode) -> BusParams {
        BusParams {
            trigger,
            i2c_hz: 400_000,
            spi_clock_hz: 40_000_000,
            t_buf_ns: 1_000_000,
            t_usb_ns: 500_000,
        }
    }

    fn board(bytes: usize) -> BoardInput {
        BoardInput {
            jitter_ns: 0,
            capture_delay_ns: 0,
            delivery_delay_ns: 0,
            frame_bytes: Some(bytes),
        }
    }

    #[test]
    fn seven_boards_at_20_kb_match_the_papers_period_plus_the_trigger() {
        let t = schedule_set(&params(TriggerMode::Broadcast), 0, &[board(20_000); 7]);
        // 43.1 µs to the capturing ACK, 1 ms buffering, 7 × 4 ms of SPI.
        assert_eq!(t.bus_free_ns, 43_100 + 1_000_000 + 7 * 4_000_000);
        assert!(t.boards.iter().all(|b| b.capture_ns == 43_100));
        assert_eq!(t.set_end_ns, t.bus_free_ns + 500_000);
    }

    #[test]
    fn sequential_trigger_staggers_captures_by_25_us() {
        let t = schedule_set(&params(TriggerMode::Sequential), 1_000, &[board(100); 3]);
        let caps: Vec<u64> = t.boards.iter().map(|b| b.capture_ns).collect();
        assert_eq!(caps, vec![21_600, 46_600, 71_600]);
    }

    #[test]
    fn a_late_board_delays_its_read_and_lost_frames_take_no_bus_time() {
        let mut boards = [board(20_000); 3];
        // Board 0's read ends at 5.04 ms; board 1 is ready only at 7.04 ms.
        boards[1].capture_delay_ns = 6_000_000;
        boards[2].frame_bytes = None;
        let t = schedule_set(&params(TriggerMode::Broadcast), 0, &boards);
        let b1 = t.boards[1];
        assert_eq!(
            b1.read_end_ns,
            Some(43_100 + 6_000_000 + 1_000_000 + 4_000_000)
        );
        assert_eq!(t.boards[2].delivered_ns, None);
        assert_eq!(t.bus_free_ns, b1.read_end_ns.unwrap_or(0));
    }
}
