//! The CDC transport against the hub firmware emulator over a real pseudo-terminal, through
//! `serialport`, the controller's acquisition loop and gate: every set arrives whole and in
//! order; an unplug shorter than the ring's span is bridged by `Resume` with no set lost or
//! duplicated; a longer one is counted `disconnected`; full-speed USB shows as a lower rate.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use gelgrip_cdc::emu::{HubEmulatorConfig, RunningHub, UsbSpeed};
use gelgrip_cdc::hub::{CdcHub, CdcHubConfig};
use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::camera::PatternCameras;
use gelgrip_controller::clock::{Clock, RealClock};
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::gate::{Gate, GateLimits};
use gelgrip_controller::hub::{BusPrediction, TriggerMode};

fn link(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("gelgrip-cdc-{name}-{}", std::process::id()))
}

fn prediction() -> BusPrediction {
    BusPrediction {
        mean_frame_bytes: 20_000.0,
        t_spi_us: 4_000.0,
        trigger_spread_us: 3.0,
        trigger_us: 50.0,
        paper_rate_hz: 30.0,
        paper_latency_us: 30_000.0,
        set_period_us: 33_000.0,
        set_latency_us: 30_000.0,
    }
}

fn serve(name: &str, boards: usize, cfg: HubEmulatorConfig) -> (RunningHub, PathBuf) {
    let path = link(name);
    let _ = std::fs::remove_file(&path);
    let hub = RunningHub::serve(
        &path,
        Box::new(PatternCameras {
            boards,
            jpeg_bytes: 20_000,
        }),
        cfg,
    )
    .expect("the emulator serves");
    (hub, path)
}

fn acquisition(path: &Path, boards: usize) -> Acquisition {
    let clock: Arc<dyn Clock> = Arc::new(RealClock::new());
    let hub = CdcHub::open(
        CdcHubConfig {
            port: path.display().to_string(),
            sensors: boards,
            trigger: TriggerMode::Broadcast,
            reconnect_s: 5.0,
            prediction: prediction(),
            cpu_clock: None,
        },
        clock.clone(),
    )
    .expect("handshake and clock sync");
    let limits = GateLimits {
        max_spread_us: 1_000,
        max_age_us: 2_000_000,
    };
    Acquisition::new(Box::new(hub), Gate::new(boards, limits), clock, 0)
}

async fn sets_for(acq: &mut Acquisition, seconds: f64) -> Vec<FrameSet> {
    let clock = RealClock::new();
    let end = clock.now_us() + (seconds * 1e6) as u64;
    let mut sets = Vec::new();
    while clock.now_us() < end {
        if let Some(set) = tokio::time::timeout(Duration::from_secs(3), acq.step())
            .await
            .expect("an event within 3 s")
            .expect("step")
        {
            sets.push(set);
        }
    }
    sets
}

fn assert_consecutive(sets: &[FrameSet], boards: usize) {
    for w in sets.windows(2) {
        assert_eq!(
            w[1].trigger_seq,
            w[0].trigger_seq.wrapping_add(1),
            "no set lost or duplicated"
        );
    }
    for set in sets {
        assert_eq!(set.frames.len(), boards);
        let cameras = PatternCameras {
            boards,
            jpeg_bytes: 20_000,
        };
        for (b, f) in set.frames.iter().enumerate() {
            assert_eq!(usize::from(f.frame.sensor.0), b);
            assert!(cameras.matches(&f.frame.jpeg, b, u64::from(set.trigger_seq)));
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sets_stream_whole_and_a_short_unplug_loses_nothing() {
    let (hub, path) = serve("short", 3, HubEmulatorConfig::default());
    let mut acq = acquisition(&path, 3);
    let mut sets = sets_for(&mut acq, 1.0).await;
    assert!(sets.len() >= 20, "{} sets in 1 s", sets.len());
    let hub = Arc::new(hub);
    let unplugger = {
        let hub = hub.clone();
        std::thread::spawn(move || hub.unplug(Duration::from_millis(300)))
    };
    sets.extend(sets_for(&mut acq, 2.0).await);
    unplugger.join().expect("thread").expect("replugged");
    assert_consecutive(&sets, 3);
    let stats = acq.gate().stats();
    assert_eq!(stats.drops.total(), 0, "{:?}", stats.drops);
    assert!(
        sets.len() >= 70,
        "{} sets in 3 s across a 0.3 s unplug",
        sets.len()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_unplug_longer_than_the_ring_is_counted_disconnected() {
    let cfg = HubEmulatorConfig {
        ring_capacity: 4,
        ..HubEmulatorConfig::default()
    };
    let (hub, path) = serve("long", 3, cfg);
    let mut acq = acquisition(&path, 3);
    sets_for(&mut acq, 0.5).await;
    let hub = Arc::new(hub);
    let unplugger = {
        let hub = hub.clone();
        std::thread::spawn(move || hub.unplug(Duration::from_millis(800)))
    };
    let after = sets_for(&mut acq, 2.0).await;
    unplugger.join().expect("thread").expect("replugged");
    assert!(after.len() >= 20, "it carries on: {}", after.len());
    let lost = acq.gate().stats().sets_rejected.disconnected;
    assert!(lost >= 10, "about 0.8 s of sets beyond the 4 held: {lost}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn full_speed_usb_limits_the_rate_not_the_frames() {
    let cfg = HubEmulatorConfig {
        usb: UsbSpeed::Full,
        ..HubEmulatorConfig::default()
    };
    let (_hub, path) = serve("fs", 7, cfg);
    let mut acq = acquisition(&path, 7);
    let sets = sets_for(&mut acq, 2.0).await;
    // 7 × 20 KB a set over about 1 MB/s: about 7 sets/s.
    assert!(
        (10..=16).contains(&sets.len()),
        "{} sets in 2 s",
        sets.len()
    );
    assert_consecutive(&sets, 7);
    assert_eq!(acq.gate().stats().drops.total(), 0);
    // Closing the host first must not hang the emulator (its writes give up).
    drop(acq);
    drop(_hub);
}
