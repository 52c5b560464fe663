//! The `latest` gate: scripted scenarios (fusion at each set end, superseded frames, frames
//! fused again, a sensor that never delivers, a silent one, reordering, corrupt frames, the
//! frame ages) and property tests on random independent streams: it never fuses a frame
//! older than one it already fused for that sensor, every frame is accounted for, and where
//! the u32 counters wrap changes nothing.

use std::collections::HashSet;

use bytes::Bytes;
use proptest::prelude::*;

use super::*;
use crate::frame::{Frame, SensorIndex};

const LIMITS: GateLimits = GateLimits {
    max_spread_us: 5,
    max_age_us: 60_000,
};

/// A frame from `sensor` captured at host `capture_us`, carrying `id` as its image.
fn frame(sensor: u8, capture_us: u64, id: u64) -> HubEvent {
    HubEvent::Frame(ReceivedFrame {
        frame: Frame {
            sensor: SensorIndex(sensor),
            trigger_seq: 0,
            capture_ts_us: capture_us as u32,
            exposure_us: 0,
            jpeg: Bytes::from(id.to_le_bytes().to_vec()),
        },
        capture_host_us: capture_us,
        received_host_us: capture_us,
    })
}

fn set_end(seq: u32) -> HubEvent {
    HubEvent::SetEnd {
        trigger_seq: seq,
        frames_sent: 0,
    }
}

fn id(f: &ReceivedFrame) -> u64 {
    let mut b = [0u8; 8];
    b.copy_from_slice(&f.frame.jpeg[..8]);
    u64::from_le_bytes(b)
}

fn ids(set: &FrameSet) -> Vec<u64> {
    set.frames.iter().map(id).collect()
}

fn accounted(gate: &LatestGate) {
    let s = gate.stats();
    assert_eq!(
        s.frames_in,
        s.frames_out + s.drops.total() + gate.pending_frames(),
        "{s:?}"
    );
}

#[test]
fn each_set_end_fuses_every_sensors_latest_frame() {
    let mut gate = LatestGate::new(3, LIMITS);
    assert!(gate.push(frame(0, 1_000, 10), 2_000).is_none());
    assert!(gate.push(frame(1, 1_400, 11), 2_100).is_none());
    assert!(gate.push(frame(2, 1_100, 12), 2_200).is_none());
    let set = gate.push(set_end(7), 3_000).expect("a set");
    assert_eq!(set.trigger_seq, 7);
    assert_eq!(ids(&set), [10, 11, 12]);
    // No window: a 400 µs spread passes a 5 µs limit, and is reported.
    assert_eq!(set.spread_us, 400);
    assert_eq!(set.earliest_capture_host_us, 1_000);
    assert_eq!(set.frame_ages_us(), [2_000, 1_600, 1_900]);
    assert_eq!(gate.stats().frames_out, 3);
    accounted(&gate);
}

#[test]
fn a_frame_replaced_before_it_was_fused_is_superseded() {
    let mut gate = LatestGate::new(2, LIMITS);
    gate.push(frame(0, 1_000, 1), 1_000);
    gate.push(frame(0, 31_000, 2), 31_000);
    gate.push(frame(1, 31_000, 3), 31_000);
    let set = gate.push(set_end(0), 32_000).expect("a set");
    assert_eq!(ids(&set), [2, 3]);
    assert_eq!(gate.stats().drops.superseded, 1);
    assert_eq!(gate.stats().drops.total(), 1);
    accounted(&gate);
}

#[test]
fn a_frame_not_replaced_is_fused_again_and_counted_once() {
    let mut gate = LatestGate::new(2, LIMITS);
    gate.push(frame(0, 1_000, 1), 1_000);
    gate.push(frame(1, 1_000, 2), 1_000);
    gate.push(set_end(0), 2_000).expect("a set");
    gate.push(frame(0, 31_000, 3), 31_000);
    let set = gate.push(set_end(1), 32_000).expect("a set");
    assert_eq!(ids(&set), [3, 2]);
    assert_eq!(set.frame_ages_us(), [1_000, 31_000]);
    let s = gate.stats();
    assert_eq!((s.sets, s.frames_out, s.frames_reused), (2, 3, 1));
    // Replacing a frame that was fused already drops nothing.
    gate.push(frame(1, 40_000, 4), 40_000);
    assert_eq!(gate.stats().drops.total(), 0);
    assert_eq!(gate.pending_frames(), 1);
    accounted(&gate);
}

#[test]
fn a_sensor_that_never_delivers_rejects_every_set_and_drops_nothing_else() {
    let mut gate = LatestGate::new(3, LIMITS);
    for k in 0..10u32 {
        let t = 1_000_000 + u64::from(k) * 30_000;
        gate.push(frame(0, t, u64::from(k) * 2), t + 100);
        gate.push(frame(1, t, u64::from(k) * 2 + 1), t + 100);
        assert!(gate.push(set_end(k), t + 5_000).is_none());
        accounted(&gate);
    }
    let s = gate.stats();
    assert_eq!(s.sets, 0);
    assert_eq!(s.sets_rejected.incomplete, 10);
    assert_eq!(s.sets_rejected.total(), 10);
    // Each frame but the last of each sensor was replaced before any set could take it.
    assert_eq!(s.drops.superseded, 18);
    assert_eq!(gate.pending_frames(), 2);
    // Once the hub reports it silent, the sets are rejected `disconnected` (before the
    // others' frames are too old, `late`).
    gate.push(
        HubEvent::Disconnected {
            sensor: SensorIndex(2),
            trigger_seq: 10,
        },
        1_400_000,
    );
    assert!(gate.push(set_end(10), 1_400_000).is_none());
    assert_eq!(gate.stats().sets_rejected.disconnected, 1);
    assert_eq!(gate.stats().sets_rejected.late, 0);
    accounted(&gate);
}

#[test]
fn a_silent_sensors_last_frame_is_fused_until_it_is_older_than_max_age() {
    let mut gate = LatestGate::new(2, LIMITS);
    let mut emitted = 0;
    for k in 0..6u32 {
        let t = 1_000_000 + u64::from(k) * 20_000;
        gate.push(frame(0, t, u64::from(k)), t);
        if k == 0 {
            gate.push(frame(1, t, 100), t);
        }
        emitted += usize::from(gate.push(set_end(k), t + 1_000).is_some());
    }
    // Sensor 1's frame is 1, 21, 41 ms old at the first three set ends: fused; then 61,
    // 81, 101 ms: rejected late.
    assert_eq!(emitted, 3);
    let s = gate.stats();
    assert_eq!(s.sets_rejected.late, 3);
    assert_eq!(s.frames_reused, 2);
    // Sensor 0's frames of the first two rejected sets were replaced before any set took
    // them.
    assert_eq!((s.drops.superseded, s.drops.total()), (2, 2));
    accounted(&gate);
    // It comes back: sets flow again.
    gate.push(frame(1, 1_120_000, 101), 1_120_000);
    assert!(gate.push(set_end(6), 1_121_000).is_some());
    accounted(&gate);
}

#[test]
fn reordered_repeated_corrupt_and_unknown_frames_are_dropped_with_their_reason() {
    let mut gate = LatestGate::new(2, LIMITS);
    gate.push(frame(0, 5_000, 1), 5_000);
    gate.push(frame(0, 4_000, 2), 5_100); // captured before the held one
    gate.push(frame(0, 5_000, 3), 5_200); // the held one's capture time again
    gate.push(frame(7, 5_000, 4), 5_300); // no such sensor
    gate.push(
        HubEvent::Corrupt {
            sensor: Some(SensorIndex(1)),
            trigger_seq: None,
            detail: "crc".into(),
        },
        5_400,
    );
    gate.push(frame(1, 5_000, 5), 5_500);
    let set = gate.push(set_end(0), 6_000).expect("a set");
    assert_eq!(ids(&set), [1, 5]);
    let d = gate.stats().drops;
    assert_eq!((d.late, d.duplicate, d.corrupt, d.total()), (1, 1, 2, 4));
    accounted(&gate);
}

/// One scripted event of an independent camera: sensor (the last value names no sensor),
/// capture offset, delay in transit, kind.
type Item = (u8, u64, u64, u8);

fn items(sensors: u8) -> impl Strategy<Value = Vec<Item>> {
    proptest::collection::vec((0..=sensors, 0u64..300_000, 0u64..90_000, 0u8..12), 0..250)
}

/// Feed the items (and a set end every 30 ms) in arrival order, with the trigger sequence
/// starting at `seq_base` and the hub's µs at `ts_base`; checks the accounting after every
/// event. The sets emitted and the gate.
fn run(sensors: u8, script: &[Item], seq_base: u32, ts_base: u32) -> (Vec<FrameSet>, LatestGate) {
    const T0: u64 = 1_000_000;
    let mut events: Vec<(u64, HubEvent)> = script
        .iter()
        .enumerate()
        .map(|(i, &(sensor, offset, delay, kind))| {
            let capture = T0
                + match kind {
                    // Repeats: a capture time other items likely share.
                    0 | 1 => offset / 20_000 * 20_000,
                    _ => offset,
                };
            let event = match kind {
                2 => HubEvent::Corrupt {
                    sensor: Some(SensorIndex(sensor)),
                    trigger_seq: None,
                    detail: String::new(),
                },
                3 => HubEvent::Disconnected {
                    sensor: SensorIndex(sensor),
                    trigger_seq: 0,
                },
                _ => {
                    let mut f = frame(sensor, capture, i as u64);
                    if let HubEvent::Frame(rf) = &mut f {
                        rf.frame.capture_ts_us = ts_base.wrapping_add((capture - T0) as u32);
                        rf.frame.trigger_seq = seq_base.wrapping_add((offset / 30_000) as u32);
                    }
                    f
                }
            };
            (capture + delay, event)
        })
        .collect();
    events.extend((0..14u32).map(|k| {
        let at = T0 + u64::from(k) * 30_000 + 29_000;
        (at, set_end(seq_base.wrapping_add(k)))
    }));
    events.sort_by_key(|(at, _)| *at);
    let mut gate = LatestGate::new(usize::from(sensors), LIMITS);
    let mut sets = Vec::new();
    for (at, event) in events {
        sets.extend(gate.push(event, at));
        gate.tick(at);
        accounted(&gate);
    }
    (sets, gate)
}

proptest! {
    #[test]
    fn latest_never_fuses_a_frame_older_than_one_it_already_fused(
        sensors in 1u8..8, script in items(7),
    ) {
        let (sets, gate) = run(sensors, &script, 0, 0);
        let mut last: Vec<Option<(u64, u64)>> = vec![None; usize::from(sensors)];
        let mut distinct = HashSet::new();
        for set in &sets {
            prop_assert_eq!(set.frames.len(), usize::from(sensors));
            prop_assert!(set.latency_us() <= LIMITS.max_age_us);
            for (s, f) in set.frames.iter().enumerate() {
                prop_assert_eq!(usize::from(f.frame.sensor.0), s);
                let now = (f.capture_host_us, id(f));
                if let Some(before) = last[s] {
                    prop_assert!(now.0 > before.0 || now == before, "{:?} after {:?}", now, before);
                }
                last[s] = Some(now);
                distinct.insert(id(f));
            }
        }
        // Every frame is accounted for: fused (once in frames_out), dropped, or held.
        let s = gate.stats();
        prop_assert_eq!(s.frames_out, distinct.len() as u64);
        prop_assert_eq!(s.frames_out + s.frames_reused, (sets.len() * usize::from(sensors)) as u64);
        prop_assert_eq!(s.frames_in, s.frames_out + s.drops.total() + gate.pending_frames());
    }

    #[test]
    fn placing_either_wrap_anywhere_changes_nothing(
        sensors in 1u8..8, script in items(7), seq_base in any::<u32>(), ts_base in any::<u32>(),
    ) {
        let (plain, g0) = run(sensors, &script, 0, 0);
        let (wrapped, g1) = run(sensors, &script, seq_base, ts_base);
        prop_assert_eq!(plain.len(), wrapped.len());
        for (a, b) in plain.iter().zip(&wrapped) {
            prop_assert_eq!(a.trigger_seq.wrapping_add(seq_base), b.trigger_seq);
            prop_assert_eq!(a.spread_us, b.spread_us);
            prop_assert_eq!(a.frame_ages_us(), b.frame_ages_us());
            prop_assert_eq!(ids(a), ids(b));
        }
        prop_assert_eq!(g0.stats().drops, g1.stats().drops);
        prop_assert_eq!(g0.stats().sets_rejected, g1.stats().sets_rejected);
    }
}

#[test]
fn steady_independent_streams_give_one_set_per_set_end_across_both_wraps() {
    // Guards the property tests above against being vacuous: 3 cameras at 30 ms, out of
    // phase, 2 ms in transit, both counters starting just before their wrap.
    let script: Vec<Item> = (0..30u64)
        .map(|i| ((i % 3) as u8, (i / 3) * 30_000 + (i % 3) * 7_000, 2_000, 5))
        .collect();
    let (sets, gate) = run(3, &script, u32::MAX - 5, u32::MAX - 100_000);
    // 14 set ends: 10 sets of fresh frames, then the last frames once more (59 ms old at
    // the 11th), then 3 sets rejected for their age.
    let s = gate.stats();
    assert_eq!(sets.len(), 11, "{s:?}");
    assert_eq!(sets[6].trigger_seq, 0, "the sequence wrapped");
    assert_eq!((s.frames_out, s.frames_reused), (30, 3));
    assert_eq!(s.sets_rejected.late, 3);
    assert_eq!(s.drops.total(), 0);
    assert!(sets.iter().all(|s| s.spread_us == 14_000));
}
