//! Gate unit and property tests.

use std::collections::HashSet;

use bytes::Bytes;
use proptest::prelude::*;

use super::*;
use crate::frame::{Frame, ReceivedFrame, SensorIndex};
use crate::hubtime::seq_newer;

const LIMITS: GateLimits = GateLimits {
    max_spread_us: 500,
    max_age_us: 60_000,
};

fn frame(sensor: u8, seq: u32, capture_ts_us: u32, host_us: u64, id: u64) -> HubEvent {
    HubEvent::Frame(ReceivedFrame {
        frame: Frame {
            sensor: SensorIndex(sensor),
            trigger_seq: seq,
            capture_ts_us,
            exposure_us: 0,
            jpeg: Bytes::from(id.to_le_bytes().to_vec()),
        },
        capture_host_us: host_us,
        received_host_us: host_us,
    })
}

fn invariant(gate: &Gate) {
    let s = gate.stats();
    assert_eq!(
        s.frames_in,
        s.frames_out + s.drops.total() + gate.pending_frames(),
        "{s:?}"
    );
}

#[test]
fn complete_sets_in_window_are_emitted() {
    let mut gate = Gate::new(3, LIMITS);
    let mut emitted = Vec::new();
    for seq in 0..5u32 {
        let t = u64::from(seq) * 30_000 + 1_000;
        for s in 0..3u8 {
            let ts = t as u32 + u32::from(s) * 25;
            if let Some(set) = gate.push(frame(s, seq, ts, t + u64::from(s) * 25, 0), t + 20_000) {
                emitted.push(set);
            }
        }
    }
    assert_eq!(emitted.len(), 5);
    assert!(
        emitted
            .iter()
            .all(|s| s.spread_us == 50 && s.frames.len() == 3)
    );
    assert_eq!(gate.stats().drops.total(), 0);
    invariant(&gate);
}

#[test]
fn a_sensor_that_keeps_capturing_late_is_excluded_and_the_rest_go_on() {
    let mut gate = Gate::new(7, LIMITS);
    let mut emitted = Vec::new();
    for seq in 0..20u32 {
        let t = u64::from(seq) * 30_000;
        for s in 0..7u8 {
            let late = if s == 4 { 2_000 } else { 0 };
            let ts = (t + late) as u32;
            if let Some(set) = gate.push(frame(s, seq, ts, t + late, 0), t + 25_000) {
                emitted.push(set);
            }
        }
        invariant(&gate);
    }
    let s = gate.stats();
    // Three refusals blamed on sensor 4 exclude it; the other 17 sets go on without it.
    assert_eq!(
        s.sets_rejected.out_of_window,
        u64::from(exclusion::EXCLUDE_AFTER_SETS)
    );
    assert_eq!(s.drops.out_of_window, 21);
    assert_eq!(s.sets, 17);
    assert_eq!(s.drops.excluded, 17, "its frames count as excluded");
    assert!(
        emitted.iter().all(|set| set.frames.len() == 6
            && set.frames.iter().all(|f| f.frame.sensor != SensorIndex(4)))
    );
    assert_eq!(
        s.excluded,
        vec![Exclusion {
            sensor: 4,
            reason: Reason::OutOfWindow,
            since_host_us: 2 * 30_000 + 25_000
        }]
    );
    assert_eq!(s.exclusions, 1);
    invariant(&gate);
}

#[test]
fn an_excluded_sensor_back_in_the_window_rejoins() {
    let mut gate = Gate::new(7, LIMITS);
    let mut sizes = Vec::new();
    // 2 ms late for 10 sets, on time afterwards; sensor 4's frame arrives last.
    for seq in 0..40u32 {
        let t = u64::from(seq) * 30_000;
        for s in [0u8, 1, 2, 3, 5, 6, 4] {
            let late = if s == 4 && seq < 10 { 2_000 } else { 0 };
            let ts = (t + late) as u32;
            if let Some(set) = gate.push(frame(s, seq, ts, t + late + 100, 0), t + 20_000) {
                sizes.push((seq, set.frames.len()));
            }
            invariant(&gate);
        }
    }
    let s = gate.stats();
    assert_eq!(s.exclusions, 1);
    assert_eq!(s.rejoins, 1);
    assert!(s.excluded.is_empty(), "back in: {:?}", s.excluded);
    // Excluded from set 3 to the tenth on-time frame; every later set has all seven.
    let rejoined = sizes
        .iter()
        .find(|(_, n)| *n == 7)
        .map(|(seq, _)| *seq)
        .expect("a full set again");
    assert!((19..=21).contains(&rejoined), "{sizes:?}");
    assert!(
        sizes
            .iter()
            .filter(|(seq, _)| *seq > rejoined)
            .all(|(_, n)| *n == 7)
    );
    assert!(
        sizes
            .iter()
            .filter(|(seq, _)| *seq < rejoined)
            .all(|(_, n)| *n == 6)
    );
    invariant(&gate);
}

#[test]
fn a_sensor_whose_frames_never_come_is_excluded_as_incomplete() {
    let mut gate = Gate::new(3, LIMITS);
    let mut emitted = 0;
    for seq in 0..10u32 {
        let t = u64::from(seq) * 30_000;
        for s in 0..2u8 {
            if gate
                .push(frame(s, seq, t as u32, t, 0), t + 1_000)
                .is_some()
            {
                emitted += 1;
            }
        }
        // The hub says it sent two frames; the third sensor is silent.
        let end = HubEvent::SetEnd {
            trigger_seq: seq,
            frames_sent: 2,
        };
        if gate.push(end, t + 2_000).is_some() {
            emitted += 1;
        }
        invariant(&gate);
    }
    let s = gate.stats();
    assert_eq!(s.sets_rejected.incomplete, 3);
    // One sensor of three may go (at most half); the sets go on with two.
    assert_eq!(s.excluded.len(), 1);
    assert_eq!(s.excluded[0].sensor, 2);
    assert_eq!(s.excluded[0].reason, Reason::Incomplete);
    assert!(emitted >= 6, "{emitted}");
}

#[test]
fn when_more_than_half_the_sensors_fail_the_sets_are_refused_as_before() {
    let mut gate = Gate::new(4, LIMITS);
    for seq in 0..20u32 {
        let t = u64::from(seq) * 30_000;
        // Only sensor 0 answers: no single sensor is to blame.
        assert!(
            gate.push(frame(0, seq, t as u32, t, 0), t + 1_000)
                .is_none()
        );
        let end = HubEvent::SetEnd {
            trigger_seq: seq,
            frames_sent: 1,
        };
        assert!(gate.push(end, t + 2_000).is_none());
    }
    let s = gate.stats();
    assert_eq!(s.sets, 0);
    assert!(s.excluded.is_empty());
    invariant(&gate);
}

#[test]
fn old_sets_are_rejected_late_and_duplicates_dropped() {
    let mut gate = Gate::new(2, LIMITS);
    assert!(gate.push(frame(0, 1, 0, 0, 1), 10).is_none());
    assert!(gate.push(frame(0, 1, 0, 0, 2), 10).is_none()); // duplicate
    assert!(gate.push(frame(1, 1, 10, 10, 3), 70_000).is_none()); // too old
    assert_eq!(gate.stats().sets_rejected.late, 1);
    assert_eq!(gate.stats().drops.duplicate, 1);
    assert!(gate.push(frame(1, 1, 10, 10, 4), 70_000).is_none()); // set closed: late frame
    assert_eq!(gate.stats().drops.late, 3);
    invariant(&gate);
}

#[test]
fn corrupt_and_missing_frames_close_the_set_at_set_end() {
    let mut gate = Gate::new(3, LIMITS);
    gate.push(frame(0, 9, 0, 0, 1), 5);
    gate.push(
        HubEvent::Corrupt {
            sensor: Some(SensorIndex(1)),
            trigger_seq: Some(9),
            detail: "crc".into(),
        },
        6,
    );
    gate.push(frame(2, 9, 0, 0, 2), 7);
    assert_eq!(gate.pending_frames(), 2);
    gate.push(
        HubEvent::SetEnd {
            trigger_seq: 9,
            frames_sent: 3,
        },
        8,
    );
    let s = gate.stats();
    assert_eq!(s.sets_rejected.corrupt, 1);
    assert_eq!(s.drops.corrupt, 3);
    invariant(&gate);
    // A set whose frames were lost entirely is still counted.
    gate.push(
        HubEvent::SetEnd {
            trigger_seq: 10,
            frames_sent: 0,
        },
        9,
    );
    assert_eq!(gate.stats().sets_rejected.incomplete, 1);
}

#[test]
fn newer_emitted_set_supersedes_unfinished_older_sets() {
    let mut gate = Gate::new(2, LIMITS);
    gate.push(frame(0, 1, 0, 0, 1), 0);
    gate.push(frame(0, 2, 0, 0, 2), 0);
    assert!(gate.push(frame(1, 2, 0, 0, 3), 0).is_some());
    assert_eq!(gate.stats().sets_rejected.incomplete, 1);
    assert!(gate.push(frame(1, 1, 0, 0, 4), 0).is_none());
    assert_eq!(gate.stats().drops.late, 1);
    invariant(&gate);
}

#[test]
fn tick_ages_out_unfinished_sets() {
    let mut gate = Gate::new(2, LIMITS);
    gate.push(frame(0, 1, 0, 100, 1), 100);
    gate.tick(50_000);
    assert_eq!(gate.pending_frames(), 1);
    gate.tick(60_101);
    assert_eq!(gate.pending_frames(), 0);
    assert_eq!(gate.stats().sets_rejected.incomplete, 1);
    invariant(&gate);
}

/// One scripted arrival: sensor, trigger offset, capture offset, arrival delay, kind.
#[derive(Debug, Clone)]
struct Arrival {
    sensor: u8,
    seq_offset: u32,
    capture_jitter_us: u32,
    delay_us: u64,
    kind: u8,
}

fn arrivals(sensors: u8) -> impl Strategy<Value = Vec<Arrival>> {
    proptest::collection::vec(
        (0..sensors + 1, 0u32..12, 0u32..800, 0u64..90_000, 0u8..10).prop_map(
            |(sensor, seq_offset, capture_jitter_us, delay_us, kind)| Arrival {
                sensor,
                seq_offset,
                capture_jitter_us,
                delay_us,
                kind,
            },
        ),
        0..200,
    )
}

/// Run a scenario with trigger sequences starting at `seq_base` and hub time at `ts_base`.
fn run(sensors: u8, script: &[Arrival], seq_base: u32, ts_base: u32) -> (Vec<FrameSet>, Gate) {
    let mut gate = Gate::new(usize::from(sensors), LIMITS);
    let mut out = Vec::new();
    let mut now = 1_000_000u64;
    for (i, a) in script.iter().enumerate() {
        // Triggers advance about one per `sensors` arrivals; arrivals may belong to the two
        // following triggers too, and arrive up to 90 ms after their trigger.
        let current = i as u32 / u32::from(sensors.max(1));
        let rel = current + a.seq_offset % 3;
        now = now.max(1_000_000 + u64::from(current) * 30_000 + a.delay_us);
        let seq = seq_base.wrapping_add(rel);
        let capture_host = 1_000_000 + u64::from(rel) * 30_000 + u64::from(a.capture_jitter_us);
        let ts = ts_base.wrapping_add((capture_host - 1_000_000) as u32);
        let event = match a.kind {
            0 => HubEvent::Corrupt {
                sensor: Some(SensorIndex(a.sensor)),
                trigger_seq: Some(seq),
                detail: String::new(),
            },
            1 => HubEvent::SetEnd {
                trigger_seq: seq,
                frames_sent: sensors,
            },
            2 => {
                gate.tick(now);
                continue;
            }
            _ => frame(a.sensor, seq, ts, capture_host, i as u64),
        };
        if let Some(set) = gate.push(event, now.max(capture_host)) {
            out.push(set);
        }
    }
    (out, gate)
}

proptest! {
    #[test]
    fn gate_never_emits_duplicate_sensors_or_reuses_frames(sensors in 1u8..8, script in arrivals(7)) {
        let (sets, gate) = run(sensors, &script, 0, 0);
        let mut used = HashSet::new();
        let mut last_seq: Option<u32> = None;
        for set in &sets {
            // Every sensor, but those excluded (at most half of them).
            let n = usize::from(sensors);
            prop_assert!(set.frames.len() <= n && set.frames.len() >= n - n / 2);
            let ids: HashSet<u8> = set.frames.iter().map(|f| f.frame.sensor.0).collect();
            prop_assert_eq!(ids.len(), set.frames.len());
            prop_assert!(set.frames.iter().all(|f| f.frame.trigger_seq == set.trigger_seq));
            prop_assert!(set.spread_us <= LIMITS.max_spread_us);
            for f in &set.frames {
                prop_assert!(used.insert(f.frame.jpeg.clone()), "frame reused");
            }
            if let Some(l) = last_seq { prop_assert!(seq_newer(set.trigger_seq, l)); }
            last_seq = Some(set.trigger_seq);
        }
        let s = gate.stats();
        prop_assert_eq!(s.frames_in, s.frames_out + s.drops.total() + gate.pending_frames());
    }

    #[test]
    fn placing_either_wrap_anywhere_changes_nothing(
        sensors in 1u8..8, script in arrivals(7), seq_base in any::<u32>(), ts_base in any::<u32>(),
    ) {
        let (plain, g0) = run(sensors, &script, 0, 0);
        let (wrapped, g1) = run(sensors, &script, seq_base, ts_base);
        prop_assert_eq!(plain.len(), wrapped.len());
        for (a, b) in plain.iter().zip(&wrapped) {
            prop_assert_eq!(a.trigger_seq.wrapping_add(seq_base), b.trigger_seq);
            prop_assert_eq!(a.spread_us, b.spread_us);
            prop_assert_eq!(a.emitted_host_us, b.emitted_host_us);
            let ja: Vec<_> = a.frames.iter().map(|f| f.frame.jpeg.clone()).collect();
            let jb: Vec<_> = b.frames.iter().map(|f| f.frame.jpeg.clone()).collect();
            prop_assert_eq!(ja, jb);
        }
        prop_assert_eq!(g0.stats().drops, g1.stats().drops);
        prop_assert_eq!(g0.stats().sets_rejected, g1.stats().sets_rejected);
    }
}

#[test]
fn scripted_scenarios_do_emit_sets() {
    // Guards the property tests above against being vacuous.
    let script: Vec<Arrival> = (0..60)
        .map(|i| Arrival {
            sensor: (i % 3) as u8,
            seq_offset: 0,
            capture_jitter_us: 10,
            delay_us: 5_000,
            kind: 5,
        })
        .collect();
    let (sets, gate) = run(3, &script, u32::MAX - 5, u32::MAX - 100_000);
    assert_eq!(sets.len(), 20, "{:?}", gate.stats());
}

/// The three policies, for `sensors` sensors with `LIMITS`.
fn every_policy(sensors: usize) -> [Gate; 3] {
    [
        Gate::new(sensors, LIMITS),
        Gate::approximate(sensors, LIMITS, 4),
        Gate::latest(sensors, LIMITS),
    ]
}

/// Feed `script` to `gate` in arrival order: each arrival belongs to trigger
/// `seq_offset % 10`, captured 30 ms apart plus its jitter and arriving its delay later; a
/// set end closes each trigger 29 ms after it. Checks the accounting after every event.
fn run_policy(mut gate: Gate, sensors: u8, script: &[Arrival]) -> (Vec<FrameSet>, Gate) {
    const T0: u64 = 1_000_000;
    let mut events: Vec<(u64, Option<HubEvent>)> = script
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let seq = a.seq_offset % 10;
            let capture = T0 + u64::from(seq) * 30_000 + u64::from(a.capture_jitter_us);
            let event = match a.kind {
                0 => Some(HubEvent::Corrupt {
                    sensor: Some(SensorIndex(a.sensor)),
                    trigger_seq: Some(seq),
                    detail: String::new(),
                }),
                1 => Some(HubEvent::Disconnected {
                    sensor: SensorIndex(a.sensor),
                    trigger_seq: seq,
                }),
                2 => None,
                _ => Some(frame(a.sensor, seq, capture as u32, capture, i as u64)),
            };
            (capture + a.delay_us, event)
        })
        .collect();
    events.extend((0..10u32).map(|seq| {
        let end = HubEvent::SetEnd {
            trigger_seq: seq,
            frames_sent: sensors,
        };
        (T0 + u64::from(seq) * 30_000 + 29_000, Some(end))
    }));
    events.sort_by_key(|(at, _)| *at);
    let mut sets = Vec::new();
    for (at, event) in events {
        match event {
            Some(e) => sets.extend(gate.push(e, at)),
            None => gate.tick(at),
        }
        invariant(&gate);
    }
    (sets, gate)
}

proptest! {
    /// Under every policy, every frame is accounted for: in an emitted set (counted once in
    /// `frames_out`, however often `latest` fuses it), dropped with a reason, or held.
    #[test]
    fn every_policy_accounts_for_every_frame(sensors in 1u8..8, script in arrivals(7)) {
        for gate in every_policy(usize::from(sensors)) {
            let policy = gate.policy();
            let (sets, gate) = run_policy(gate, sensors, &script);
            let mut distinct = HashSet::new();
            for set in &sets {
                let n = usize::from(sensors);
                let ids: HashSet<u8> = set.frames.iter().map(|f| f.frame.sensor.0).collect();
                prop_assert_eq!(ids.len(), set.frames.len(), "{}", policy);
                if policy != "latest" {
                    // Every sensor, but those excluded (at most half of them).
                    prop_assert!(set.frames.len() >= n - n / 2, "{}", policy);
                } else {
                    prop_assert_eq!(set.frames.len(), n, "{}", policy);
                }
                distinct.extend(set.frames.iter().map(|f| f.frame.jpeg.clone()));
            }
            let s = gate.stats();
            prop_assert_eq!(s.frames_out, distinct.len() as u64, "{}", policy);
            prop_assert_eq!(
                s.frames_in,
                s.frames_out + s.drops.total() + gate.pending_frames(),
                "{}", policy
            );
        }
    }
}

#[test]
fn a_capture_that_holds_up_the_readout_is_named_from_the_late_frames() {
    // Sensor 0 captures 40 ms late and holds up the readout of sensors 2 and 3: each set,
    // opened by sensor 1's frame on time, ages out with three sensors missing (nobody to
    // blame yet). The frames that then arrive name the capture out of step, and the sensor
    // is excluded for it; the readout is still held up, so no set passes and the fingers
    // hold, but the run says which sensor and why.
    let mut gate = Gate::new(4, LIMITS);
    let push = |gate: &mut Gate, s: u8, seq: u32, capture: u64, arrival: u64| {
        let HubEvent::Frame(mut rf) = frame(s, seq, capture as u32, capture, 0) else {
            unreachable!("frame() makes frames")
        };
        rf.received_host_us = arrival;
        assert!(gate.push(HubEvent::Frame(rf), arrival).is_none());
    };
    for seq in 0..12u32 {
        let t = u64::from(seq) * 30_000;
        push(&mut gate, 1, seq, t, t + 1_000);
        gate.tick(t + 61_000);
        push(&mut gate, 0, seq, t + 40_000, t + 70_000);
        push(&mut gate, 2, seq, t, t + 70_100);
        push(&mut gate, 3, seq, t, t + 70_200);
        invariant(&gate);
    }
    let s = gate.stats();
    assert_eq!(s.sets, 0, "the readout is still held up: the fingers hold");
    assert!(s.sets_rejected.incomplete >= 10, "{:?}", s.sets_rejected);
    assert_eq!(s.excluded.len(), 1, "{:?}", s.excluded);
    assert_eq!(s.excluded[0].sensor, 0);
    assert_eq!(s.excluded[0].reason, Reason::OutOfWindow);
}

#[test]
fn sets_overtaken_in_flight_blame_nobody() {
    // Sensor 2, read last, has its readout held up: its frames for sets k, k+1 and k+2
    // come only after set k+3 completed. Those three sets are refused `incomplete`, but
    // sensor 2 did nothing wrong, so it stays in, and every overtaking set passes whole.
    let mut gate = Gate::new(3, LIMITS);
    let mut sets = Vec::new();
    let mut id = 0;
    let mut push = |gate: &mut Gate, s: u8, seq: u32, arrival: u64| {
        let t = u64::from(seq) * 10_000;
        id += 1;
        let HubEvent::Frame(mut rf) = frame(s, seq, t as u32, t, id) else {
            unreachable!("frame() makes frames")
        };
        rf.received_host_us = arrival;
        gate.push(HubEvent::Frame(rf), arrival)
    };
    for group in 0..4u32 {
        let first = 4 * group;
        for seq in first..first + 3 {
            let t = u64::from(seq) * 10_000;
            assert!(push(&mut gate, 0, seq, t + 1_000).is_none());
            assert!(push(&mut gate, 1, seq, t + 2_000).is_none());
        }
        let last = first + 3;
        let t = u64::from(last) * 10_000;
        sets.extend(push(&mut gate, 0, last, t + 1_000));
        sets.extend(push(&mut gate, 1, last, t + 2_000));
        sets.extend(push(&mut gate, 2, last, t + 3_000));
        for seq in first..last {
            assert!(push(&mut gate, 2, seq, t + 4_000).is_none(), "late");
        }
        invariant(&gate);
    }
    let s = gate.stats();
    assert!(s.excluded.is_empty(), "{:?}", s.excluded);
    assert_eq!(sets.len(), 4);
    assert!(sets.iter().all(|set| set.frames.len() == 3));
    assert_eq!(s.sets_rejected.incomplete, 12);
}

#[test]
fn a_set_aged_out_while_the_hub_still_reads_it_blames_nobody() {
    // Sensor 2, read last, comes after the age limit on every set because another board's
    // capture held the readout up; the hub's set end follows it. The sets are refused
    // `incomplete`, but sensor 2 lost nothing, so it stays in. A silent sensor, whose
    // set end says it was not sent, is still blamed (the dead-sensor tests).
    let mut gate = Gate::new(3, LIMITS);
    for seq in 0..6u32 {
        let t = u64::from(seq) * 30_000;
        let push = |gate: &mut Gate, s: u8, arrival: u64| {
            let HubEvent::Frame(mut rf) =
                frame(s, seq, t as u32, t, u64::from(seq * 3) + u64::from(s))
            else {
                unreachable!("frame() makes frames")
            };
            rf.received_host_us = arrival;
            assert!(gate.push(HubEvent::Frame(rf), arrival).is_none());
        };
        push(&mut gate, 0, t + 1_000);
        push(&mut gate, 1, t + 2_000);
        gate.tick(t + 61_000);
        push(&mut gate, 2, t + 62_000);
        let end = HubEvent::SetEnd {
            trigger_seq: seq,
            frames_sent: 3,
        };
        assert!(gate.push(end, t + 62_100).is_none());
        invariant(&gate);
    }
    let s = gate.stats();
    assert_eq!(s.sets_rejected.incomplete, 6);
    assert!(s.excluded.is_empty(), "{:?}", s.excluded);
}
