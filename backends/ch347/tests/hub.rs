//! The hub protocol through the CH347 driver, end to end on the chip emulator with emulated
//! sensor boards: the acquisition loop and gate of the controller get every board's frame,
//! CRC-checked, with broadcast and sequential triggers; paced on a virtual clock, the set
//! rate is the modelled bus's; a dead board, corrupt bytes and a late capture show up as
//! the gate's `disconnected`, `corrupt` and `out_of_window`.

use std::sync::Arc;

use gelgrip_ch347::Ch347;
use gelgrip_ch347::board::{BoardFaults, Boards};
use gelgrip_ch347::emu::Ch347Emulator;
use gelgrip_ch347::hub::{Ch347Hub, Ch347HubConfig};
use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::camera::PatternCameras;
use gelgrip_controller::clock::{Clock, VirtualClock};
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::gate::{Gate, GateLimits};
use gelgrip_controller::hub::{HubTransport, TriggerMode};

fn emulated_hub(
    n: usize,
    trigger: TriggerMode,
    faults: &[(usize, BoardFaults)],
) -> (Ch347Hub<Ch347Emulator>, Arc<VirtualClock>) {
    let clock = VirtualClock::new();
    let mut emu = Ch347Emulator::new();
    let mut cfg = Ch347HubConfig::default_for(n, trigger);
    cfg.pace = true;
    cfg.mean_frame_bytes = 20_000.0;
    let c = clock.clone();
    let boards = Boards::attach(
        &mut emu,
        Box::new(PatternCameras {
            boards: n,
            jpeg_bytes: 20_000,
        }),
        &cfg.cs,
        Arc::new(move || c.now_us()),
    );
    for (i, f) in faults {
        boards.set_faults(*i, *f);
    }
    let hub = Ch347Hub::open(Ch347::new(emu), cfg, clock.clone()).expect("hub opens");
    (hub, clock)
}

async fn run(
    hub: Ch347Hub<Ch347Emulator>,
    clock: Arc<VirtualClock>,
    sets_wanted: usize,
    limits: GateLimits,
) -> (Vec<FrameSet>, Acquisition) {
    let n = hub.describe().sensors;
    let mut acq = Acquisition::new(
        Box::new(hub),
        Gate::new(n, limits).without_exclusion(),
        clock.clone(),
        100,
    );
    let mut sets = Vec::new();
    // Enough steps for `sets_wanted` sets (each set is 2 + 7 events), or for 10 triggers
    // when none is expected.
    for _ in 0..sets_wanted.max(10) * 20 {
        if let Some(set) = acq.step().await.expect("step") {
            sets.push(set);
            if sets.len() == sets_wanted {
                break;
            }
        }
    }
    (sets, acq)
}

const LIMITS: GateLimits = GateLimits {
    max_spread_us: 1_000,
    max_age_us: 500_000,
};

#[tokio::test]
async fn broadcast_sets_carry_every_boards_frame_at_the_modelled_rate() {
    let (hub, clock) = emulated_hub(7, TriggerMode::Broadcast, &[]);
    let predicted_hz = 1e6 / hub.describe().prediction.set_period_us;
    let (sets, acq) = run(hub, clock.clone(), 20, LIMITS).await;
    assert_eq!(sets.len(), 20, "{:?}", acq.gate().stats().drops);
    for (k, set) in sets.iter().enumerate() {
        assert_eq!(set.trigger_seq, 100 + k as u32);
        assert_eq!(set.frames.len(), 7);
        assert_eq!(set.spread_us, 0, "one general call stamps every board");
        let cameras = PatternCameras {
            boards: 7,
            jpeg_bytes: 20_000,
        };
        for (b, f) in set.frames.iter().enumerate() {
            assert_eq!(usize::from(f.frame.sensor.0), b);
            assert!(cameras.matches(&f.frame.jpeg, b, k as u64), "capture {k}");
        }
    }
    let stats = acq.gate().stats();
    assert_eq!(stats.drops.total(), 0);
    // 7 × 20 KB at 30 MHz plus turnarounds: about 25 sets/s; the rate is the bus model's
    // within the turnarounds it does not count.
    let rate = stats.set_rate_hz();
    assert!(
        rate > 0.8 * predicted_hz && rate < 1.05 * predicted_hz,
        "{rate} Hz vs {predicted_hz} Hz"
    );
}

#[tokio::test]
async fn sequential_triggers_stagger_the_captures() {
    let (hub, clock) = emulated_hub(3, TriggerMode::Sequential, &[]);
    let (sets, _) = run(hub, clock, 5, LIMITS).await;
    assert_eq!(sets.len(), 5);
    for set in &sets {
        // One I2C stream of address-only writes: the boards capture one transfer (25 µs at
        // 400 kHz, docs/protocol.md §3) apart.
        assert_eq!(set.spread_us, 50);
    }
}

#[tokio::test]
async fn a_dead_board_corrupt_bytes_and_a_late_capture_are_counted_by_reason() {
    let dead = BoardFaults {
        dead: true,
        ..BoardFaults::default()
    };
    let (hub, clock) = emulated_hub(3, TriggerMode::Broadcast, &[(1, dead)]);
    let (sets, acq) = run(hub, clock, 0, LIMITS).await;
    assert!(sets.is_empty());
    let s = acq.gate().stats();
    assert!(s.sets_rejected.disconnected >= 5, "{:?}", s.sets_rejected);
    assert_eq!(s.sets_rejected.total(), s.sets_rejected.disconnected);

    let corrupt = BoardFaults {
        corrupt_every: 2,
        ..BoardFaults::default()
    };
    let (hub, clock) = emulated_hub(3, TriggerMode::Broadcast, &[(2, corrupt)]);
    let (sets, acq) = run(hub, clock, 10, LIMITS).await;
    assert_eq!(sets.len(), 10, "every other set survives");
    let s = acq.gate().stats();
    assert!(
        s.drops.corrupt >= 9 && s.sets_rejected.corrupt >= 9,
        "{:?}",
        s.drops
    );

    let late = BoardFaults {
        capture_delay_us: 5_000,
        ..BoardFaults::default()
    };
    let (hub, clock) = emulated_hub(3, TriggerMode::Broadcast, &[(0, late)]);
    let (sets, acq) = run(hub, clock, 0, LIMITS).await;
    assert!(sets.is_empty());
    assert!(acq.gate().stats().sets_rejected.out_of_window >= 5);
}
