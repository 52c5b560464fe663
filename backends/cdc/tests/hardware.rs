//! Hardware test: [`CdcHub`] on a real MCU hub: the handshake and clock sync, `Start`, then
//! ten whole sets in order through the controller's gate.
//!
//! `GELGRIP_CDC_PORT=/dev/ttyACM0 GELGRIP_CDC_SENSORS=7 cargo test -p gelgrip-cdc --features
//! hardware-tests --test hardware`. With the feature on, a missing `GELGRIP_CDC_PORT` fails
//! loudly; without it the test is ignored.

use std::sync::Arc;
use std::time::Duration;

use gelgrip_cdc::hub::{CdcHub, CdcHubConfig};
use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::clock::{Clock, RealClock};
use gelgrip_controller::gate::{Gate, GateLimits};
use gelgrip_controller::hub::{BusPrediction, TriggerMode};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(not(feature = "hardware-tests"), ignore)]
async fn a_real_hub_streams_whole_sets_in_order() {
    let port = std::env::var("GELGRIP_CDC_PORT").unwrap_or_else(|_| {
        panic!(
            "GELGRIP_CDC_PORT is not set: hardware tests need the hub's port, e.g. \
             GELGRIP_CDC_PORT=/dev/ttyACM0 cargo test -p gelgrip-cdc --features hardware-tests --test hardware"
        )
    });
    let sensors: usize = std::env::var("GELGRIP_CDC_SENSORS")
        .unwrap_or_else(|_| "7".into())
        .parse()
        .expect("GELGRIP_CDC_SENSORS: a number of boards");
    let clock: Arc<dyn Clock> = Arc::new(RealClock::new());
    let hub = CdcHub::open(
        CdcHubConfig {
            port,
            sensors,
            trigger: TriggerMode::Broadcast,
            reconnect_s: 5.0,
            prediction: BusPrediction {
                mean_frame_bytes: 20_000.0,
                t_spi_us: 4_000.0,
                trigger_spread_us: 50.0,
                trigger_us: 50.0,
                paper_rate_hz: 30.0,
                paper_latency_us: 30_000.0,
                set_period_us: 33_000.0,
                set_latency_us: 30_000.0,
            },
            cpu_clock: None,
        },
        clock.clone(),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let limits = GateLimits {
        max_spread_us: 1_000,
        max_age_us: 500_000,
    };
    let mut acq = Acquisition::new(Box::new(hub), Gate::new(sensors, limits), clock, 0);
    let mut sets = Vec::new();
    while sets.len() < 10 {
        let step = tokio::time::timeout(Duration::from_secs(5), acq.step())
            .await
            .expect("an event within 5 s")
            .expect("the hub answers");
        sets.extend(step);
    }
    for w in sets.windows(2) {
        assert_eq!(w[1].trigger_seq, w[0].trigger_seq.wrapping_add(1));
    }
    assert!(sets.iter().all(|s| s.frames.len() == sensors));
}
