//! The per-sensor timing faults as the hub's frames show them: capture jitter and a
//! drifting board clock.

use super::*;
use gelgrip_controller::clock::VirtualClock;
use gelgrip_controller::config::{BackendSection, DiskFiles, FieldCheck};
use gelgrip_controller::hubtime::signed_diff;

/// A three-sensor hub (`s1`…`s3`, broadcast: every board acknowledges at once) whose
/// `[hub.sim]` section is `extra`, on a virtual clock.
fn hub(extra: &str) -> (SimHub, Arc<VirtualClock>) {
    let layout = HandLayout::generated(3).expect("layout");
    let text = format!("noise_pool = 1\ncapture_jitter_us = 0\n{extra}");
    let section = BackendSection {
        check: FieldCheck::new("test.toml"),
        prefix: "hub.sim".into(),
        table: toml::from_str(&text).expect("TOML"),
        base_dir: ".".into(),
        files: Arc::new(DiskFiles),
    };
    let cfg = SimConfig::from_section(&section, &layout).expect("config");
    let clock = VirtualClock::new();
    let hub = SimHub::new(&layout, TriggerMode::Broadcast, cfg, clock.clone()).expect("hub");
    (hub, clock)
}

/// Fire trigger `seq` and collect its frames, by sensor.
async fn set(hub: &mut SimHub, seq: u32) -> Vec<ReceivedFrame> {
    hub.trigger(seq).await.expect("trigger");
    let mut frames = Vec::new();
    loop {
        match hub.next_event().await.expect("event") {
            HubEvent::Frame(f) => frames.push(f),
            HubEvent::SetEnd { trigger_seq, .. } if trigger_seq == seq => break,
            other => panic!("unexpected {other:?}"),
        }
    }
    frames.sort_by_key(|f| f.frame.sensor.0);
    assert_eq!(frames.len(), 3, "set {seq}");
    frames
}

/// How much later than sensor 0 sensor `b` says it captured, µs (wrap-safe).
fn lag_us(frames: &[ReceivedFrame], b: usize) -> i64 {
    signed_diff(frames[b].frame.capture_ts_us, frames[0].frame.capture_ts_us)
}

async fn jitter_lags(seed: u64) -> Vec<i64> {
    let (mut hub, _) = hub(&format!(
        "seed = {seed}\n[[faults]]\nsensor = \"s2\"\ncapture_jitter_us = 400\n"
    ));
    let mut lags = Vec::new();
    for seq in 0..300 {
        let frames = set(&mut hub, seq).await;
        assert_eq!(lag_us(&frames, 2), 0, "the other sensors keep time");
        lags.push(lag_us(&frames, 1));
    }
    lags
}

#[tokio::test]
async fn jitter_spreads_each_capture_within_its_bound_and_repeats_for_a_seed() {
    let lags = jitter_lags(7).await;
    assert!(lags.iter().all(|l| (0..=400).contains(l)), "{lags:?}");
    let mean = lags.iter().sum::<i64>() as f64 / lags.len() as f64;
    assert!(
        (170.0..230.0).contains(&mean),
        "uniform on 0..=400: mean {mean}"
    );
    assert!(lags.iter().any(|l| *l < 40) && lags.iter().any(|l| *l > 360));
    let mut distinct = lags.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert!(distinct.len() > 150, "drawn afresh per frame: {distinct:?}");
    assert_eq!(jitter_lags(7).await, lags, "deterministic for a seed");
    assert_ne!(jitter_lags(8).await, lags, "another seed, other draws");
}

/// Sensor `s2`'s stamp against the others' at triggers every 2.5 s for 10 s, µs.
async fn drift_lags(drift_ppm: f64, hub_clock_start_us: u32) -> Vec<(u64, i64, i64)> {
    let (mut hub, clock) = hub(&format!(
        "hub_clock_start_us = {hub_clock_start_us}\n\
         [[faults]]\nsensor = \"s2\"\nclock_drift_ppm = {drift_ppm}\n"
    ));
    let mut out = Vec::new();
    for seq in 0..=4u32 {
        let at_us = u64::from(seq) * 2_500_000;
        clock.sleep_until(at_us).await;
        let frames = set(&mut hub, seq).await;
        let host_lag = frames[1].capture_host_us as i64 - frames[0].capture_host_us as i64;
        out.push((at_us, lag_us(&frames, 1), host_lag));
    }
    out
}

#[tokio::test]
async fn a_drifting_clock_stamps_drift_times_elapsed_across_the_wrap() {
    // The hub's counter wraps 4 s in; the drift starts at the first trigger.
    let start = u32::MAX - 4_000_000;
    for drift_ppm in [100.0, -100.0, 1000.0, -1000.0] {
        for (at_us, lag, host_lag) in drift_lags(drift_ppm, start).await {
            let expected = (drift_ppm * at_us as f64 / 1e6).round() as i64;
            assert!(
                (lag - expected).abs() <= 1,
                "{drift_ppm} ppm at {at_us} µs: {lag} µs, expected {expected}"
            );
            assert_eq!(host_lag, lag, "the host times follow the stamps");
        }
    }
    let ten_s = drift_lags(100.0, 0).await[4];
    assert_eq!(ten_s.0, 10_000_000);
    assert!(
        (999..=1001).contains(&ten_s.1),
        "100 ppm over 10 s: {ten_s:?}"
    );
}
