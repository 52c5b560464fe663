//! One transport conformance suite: the same test bodies run against the simulated hub, the
//! CH347 (its chip emulator on an emulated USB port) and the CDC hub (its firmware emulator
//! on a pseudo-terminal, through `serialport`), each through the controller's acquisition
//! loop and gate on the real clock.
//!
//! Every body ends with the same bookkeeping: emitted sets are in order and never repeat,
//! every set up to the last one emitted was decided (emitted, or rejected with a reason),
//! and every frame the gate was given is delivered, dropped with a reason, or still pending.

mod rig;

use std::collections::BTreeSet;
use std::time::Duration;

use gelgrip_controller::camera::BoardFaults;
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::gate::Reason;
use rig::{Kind, LIMITS, Rig, SENSORS};

/// The bookkeeping every body ends with.
fn assert_accounted(rig: &Rig, sets: &[FrameSet]) {
    let kind = rig.kind;
    for w in sets.windows(2) {
        assert!(
            w[1].trigger_seq > w[0].trigger_seq,
            "{kind:?}: set {} after set {}",
            w[1].trigger_seq,
            w[0].trigger_seq
        );
    }
    let s = rig.stats();
    assert_eq!(s.sets, sets.len() as u64, "{kind:?}");
    let decided = s.sets + s.sets_rejected.total();
    if let Some(last) = sets.last() {
        assert!(
            decided > u64::from(last.trigger_seq),
            "{kind:?}: sets 0..={} but only {decided} decided ({:?})",
            last.trigger_seq,
            s.sets_rejected
        );
    }
    let pending = rig.acq.gate().pending_frames();
    assert_eq!(
        s.frames_in,
        s.frames_out + s.drops.total() + pending,
        "{kind:?}: frames in = out + dropped + pending ({:?})",
        s.drops
    );
}

/// At least `at_least` sets were rejected, all for `reason`.
fn assert_rejected_only(rig: &Rig, reason: Reason, at_least: u64) {
    let rejected = &rig.stats().sets_rejected;
    let kind = rig.kind;
    assert!(rejected.get(reason) >= at_least, "{kind:?}: {rejected:?}");
    assert_eq!(
        rejected.total(),
        rejected.get(reason),
        "{kind:?}: {rejected:?}"
    );
}

/// Each emitted set has one whole frame of every sensor, all of its trigger.
fn assert_whole(rig: &Rig, sets: &[FrameSet]) {
    for set in sets {
        let sensors: BTreeSet<u8> = set.frames.iter().map(|f| f.frame.sensor.0).collect();
        assert_eq!(
            sensors.len(),
            SENSORS,
            "{:?}: set {}",
            rig.kind,
            set.trigger_seq
        );
        assert_eq!(set.frames.len(), SENSORS);
        for f in &set.frames {
            assert_eq!(f.frame.trigger_seq, set.trigger_seq, "{:?}", rig.kind);
            assert!(
                rig.frame_is_whole(&f.frame),
                "{:?}: a broken frame",
                rig.kind
            );
        }
    }
}

/// Sets are consecutive: nothing between them was lost.
fn assert_consecutive(rig: &Rig, sets: &[FrameSet]) {
    for w in sets.windows(2) {
        assert_eq!(
            w[1].trigger_seq,
            w[0].trigger_seq + 1,
            "{:?}: a gap ({:?})",
            rig.kind,
            rig.stats().sets_rejected
        );
    }
}

async fn frames_arrive_whole_once_and_in_order(kind: Kind, name: &str) {
    let mut rig = Rig::open(kind, name);
    let sets = rig.run_for(2.0).await;
    assert!(sets.len() >= 30, "{kind:?}: {} sets in 2 s", sets.len());
    assert_whole(&rig, &sets);
    assert_consecutive(&rig, &sets);
    assert_eq!(
        rig.stats().drops.total(),
        0,
        "{kind:?}: {:?}",
        rig.stats().drops
    );
    assert_eq!(rig.stats().sets_rejected.total(), 0, "{kind:?}");
    assert_accounted(&rig, &sets);
}

async fn gate_statistics_match_what_was_delivered(kind: Kind, name: &str) {
    let mut rig = Rig::open(kind, name);
    let sets = rig.run_for(2.0).await;
    let s = rig.stats();
    assert_eq!(s.frames_out, (SENSORS * sets.len()) as u64, "{kind:?}");
    let widest = sets.iter().map(|s| s.spread_us).max().unwrap_or(0);
    assert!(widest <= LIMITS.max_spread_us, "{kind:?}: {widest} µs");
    assert_eq!(
        s.spread_us.max(),
        u64::from(widest),
        "{kind:?}: the histogram's widest spread"
    );
    let (first, last) = (sets.first().expect("sets"), sets.last().expect("sets"));
    let span_s = (last.emitted_host_us - first.emitted_host_us) as f64 / 1e6;
    let measured_hz = (sets.len() - 1) as f64 / span_s;
    let rel = (s.set_rate_hz() - measured_hz).abs() / measured_hz;
    assert!(
        rel < 0.05,
        "{kind:?}: gate says {} Hz, sets {measured_hz} Hz",
        s.set_rate_hz()
    );
    let p50 = s.latency_us_quantile(0.5).expect("latency");
    let slowest = sets.iter().map(FrameSet::latency_us).max().unwrap_or(0);
    assert!(
        p50 > 0 && p50 <= slowest + slowest / 100 + 1,
        "{kind:?}: p50 {p50} µs"
    );
    assert_accounted(&rig, &sets);
}

async fn corrupt_bytes_are_caught_and_never_delivered(kind: Kind, name: &str) {
    let mut rig = Rig::open(kind, name);
    rig.set_faults(
        3,
        BoardFaults {
            corrupt_every: 3,
            ..BoardFaults::default()
        },
    );
    let sets = rig.run_for(2.5).await;
    let s = rig.stats();
    assert!(s.drops.corrupt >= 5, "{kind:?}: {:?}", s.drops);
    assert_rejected_only(&rig, Reason::Corrupt, 5);
    assert!(
        sets.len() >= 10,
        "{kind:?}: the other sets pass ({})",
        sets.len()
    );
    assert_whole(&rig, &sets);
    assert_accounted(&rig, &sets);
}

async fn unplug_and_replug_mid_stream(kind: Kind, name: &str) {
    let mut rig = Rig::open(kind, name);
    let mut sets = rig.run_for(1.0).await;
    let before = sets
        .last()
        .map(|s| s.trigger_seq)
        .expect("sets before the unplug");
    rig.unplug(Duration::from_millis(300));
    sets.extend(rig.run_for(2.5).await);
    let after = sets.iter().filter(|s| s.trigger_seq > before + 20).count();
    assert!(after >= 10, "{kind:?}: {after} sets after the replug");
    assert_whole(&rig, &sets);
    let s = rig.stats();
    if rig.buffers_sets() {
        // The hub's ring bridges the outage: nothing the device produced is lost.
        assert_eq!(
            s.sets_rejected.total(),
            0,
            "{kind:?}: {:?}",
            s.sets_rejected
        );
        // Frames of a set cut off by the unplug are replayed once, not twice.
        assert_eq!(s.drops.total(), 0, "{kind:?}: {:?}", s.drops);
        assert_consecutive(&rig, &sets);
    } else {
        // No trigger reached the boards: each is counted disconnected, nothing else.
        assert_rejected_only(&rig, Reason::Disconnected, 3);
    }
    assert_accounted(&rig, &sets);
}

async fn a_long_outage_is_counted_disconnected(kind: Kind, name: &str) {
    let mut rig = Rig::open(kind, name);
    let mut sets = rig.run_for(0.8).await;
    rig.unplug(Duration::from_millis(1_300));
    sets.extend(rig.run_for(3.0).await);
    // 1.3 s is longer than the CDC hub's ring (16 sets, about 0.5 s).
    assert_rejected_only(&rig, Reason::Disconnected, 10);
    let last = sets.last().expect("sets after the outage");
    assert!(
        last.emitted_host_us > sets[0].emitted_host_us + 3_000_000,
        "{kind:?}: the stream came back"
    );
    assert_whole(&rig, &sets);
    assert_accounted(&rig, &sets);
}

async fn a_missing_sensor_is_reported_disconnected(kind: Kind, name: &str) {
    let mut rig = Rig::open(kind, name);
    let dead = BoardFaults {
        dead: true,
        ..BoardFaults::default()
    };
    rig.set_faults(5, dead);
    let mut sets = rig.run_for(1.5).await;
    // A set or two may have been on its way before the board died.
    assert!(
        sets.len() <= 2,
        "{kind:?}: {} sets without sensor 5",
        sets.len()
    );
    assert_rejected_only(&rig, Reason::Disconnected, 20);
    rig.set_faults(5, BoardFaults::default());
    sets.extend(rig.run_for(1.0).await);
    assert!(
        sets.len() >= 12,
        "{kind:?}: {} sets once it is back",
        sets.len()
    );
    assert_whole(&rig, &sets);
    assert_accounted(&rig, &sets);
}

async fn a_slow_sensor_widens_the_spread_until_the_gate_refuses(kind: Kind, name: &str) {
    let mut rig = Rig::open(kind, name);
    let slow = |us| BoardFaults {
        capture_delay_us: us,
        ..BoardFaults::default()
    };
    rig.set_faults(2, slow(400));
    let mut sets = rig.run_for(1.5).await;
    // Skip the sets captured before the fault.
    let late: Vec<_> = sets.iter().skip(4).collect();
    assert!(late.len() >= 15, "{kind:?}: {} sets", late.len());
    for set in &late {
        assert!(
            (390..=LIMITS.max_spread_us).contains(&set.spread_us),
            "{kind:?}: set {} spread {} µs",
            set.trigger_seq,
            set.spread_us
        );
    }
    rig.set_faults(2, slow(5_000));
    let refused = rig.run_for(1.5).await;
    assert!(
        refused.len() <= 3,
        "{kind:?}: {} sets past 1 ms",
        refused.len()
    );
    assert_rejected_only(&rig, Reason::OutOfWindow, 15);
    sets.extend(refused);
    assert_whole(&rig, &sets);
    assert_accounted(&rig, &sets);
}

/// One test per body and transport: `sim::…`, `ch347::…`, `cdc::…`.
macro_rules! suite {
    ($transport:ident, $kind:expr, [$($body:ident),* $(,)?]) => {
        mod $transport {
            $(
                #[tokio::test]
                async fn $body() {
                    let name = concat!(stringify!($transport), "-", stringify!($body));
                    super::$body($kind, name).await;
                }
            )*
        }
    };
}

macro_rules! every_transport {
    ($($body:ident),* $(,)?) => {
        suite!(sim, super::Kind::Sim, [$($body),*]);
        suite!(ch347, super::Kind::Ch347, [$($body),*]);
        suite!(cdc, super::Kind::Cdc, [$($body),*]);
    };
}

every_transport!(
    frames_arrive_whole_once_and_in_order,
    gate_statistics_match_what_was_delivered,
    corrupt_bytes_are_caught_and_never_delivered,
    unplug_and_replug_mid_stream,
    a_long_outage_is_counted_disconnected,
    a_missing_sensor_is_reported_disconnected,
    a_slow_sensor_widens_the_spread_until_the_gate_refuses,
);
