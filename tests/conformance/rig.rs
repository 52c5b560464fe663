//! One rig per transport: the product's hub transport (sim, CH347 over the chip emulator,
//! CDC over a pseudo-terminal to the hub firmware emulator), the controller's acquisition
//! loop and gate on the real clock, and a handle to inject the same faults into each
//! device.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use gelgrip_cdc::emu::{HubEmulatorConfig, RunningHub, UsbSpeed};
use gelgrip_cdc::hub::{CdcHub, CdcHubConfig};
use gelgrip_ch347::Ch347;
use gelgrip_ch347::board::Boards;
use gelgrip_ch347::emu::Ch347Emulator;
use gelgrip_ch347::hub::{Ch347Hub, Ch347HubConfig};
use gelgrip_ch347::plug::EmulatedPort;
use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::camera::{BoardFaults, PatternCameras};
use gelgrip_controller::clock::{Clock, RealClock};
use gelgrip_controller::config::{BackendSection, DiskFiles, FieldCheck};
use gelgrip_controller::frame::{Frame, FrameSet};
use gelgrip_controller::gate::{Gate, GateLimits, GateStats};
use gelgrip_controller::hub::{HubTransport, TriggerMode};
use gelgrip_controller::layout::HandLayout;
use gelgrip_sim::config::{SensorFaults, SimConfig};
use gelgrip_sim::hub::SimHub;
use gelgrip_sim::world::{SharedWorld, World};

/// The sensors of every rig (the gripper's seven).
pub const SENSORS: usize = 7;
/// Size of the emulated boards' frames, bytes (the paper's S).
const JPEG_BYTES: usize = 20_000;
/// Sets the CDC hub keeps for `Resume` (about 0.45 s at 34 Hz, so a test can outlast it).
pub const CDC_RING_SETS: u16 = 16;

/// The gate every rig uses: 1 ms of spread; a generous age, so sets replayed after a
/// replug still pass (the suite checks nothing is lost, not that it is fresh).
pub const LIMITS: GateLimits = GateLimits {
    max_spread_us: 1_000,
    max_age_us: 3_000_000,
};

/// Which transport.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The simulated hub.
    Sim,
    /// A CH347 bridge (the chip emulator on an emulated USB port).
    Ch347,
    /// An MCU hub over USB-CDC (the firmware emulator on a pseudo-terminal).
    Cdc,
}

enum Device {
    Sim(SharedWorld),
    Ch347 { boards: Boards, port: EmulatedPort },
    Cdc(Arc<RunningHub>, PathBuf),
}

/// A transport, its acquisition loop and its device.
pub struct Rig {
    /// Which transport.
    pub kind: Kind,
    /// The acquisition loop (hub and gate).
    pub acq: Acquisition,
    device: Device,
    clock: Arc<dyn Clock>,
}

fn sim_config(layout: &HandLayout) -> SimConfig {
    let section = BackendSection {
        check: FieldCheck::new("conformance"),
        prefix: "hub.sim".into(),
        table: toml::Table::new(),
        base_dir: ".".into(),
        files: Arc::new(DiskFiles),
    };
    SimConfig::from_section(&section, layout).expect("default sim config")
}

fn cameras() -> Box<PatternCameras> {
    Box::new(PatternCameras {
        boards: SENSORS,
        jpeg_bytes: JPEG_BYTES,
    })
}

impl Rig {
    /// Open `kind`'s transport (`name` keeps the CDC links of parallel tests apart).
    pub fn open(kind: Kind, name: &str) -> Self {
        let clock: Arc<dyn Clock> = Arc::new(RealClock::new());
        let layout = HandLayout::generated(SENSORS).expect("layout");
        let (hub, device): (Box<dyn HubTransport>, Device) = match kind {
            Kind::Sim => {
                let world = World::new(&layout, None).into_shared();
                let hub = SimHub::with_world(
                    &layout,
                    TriggerMode::Broadcast,
                    sim_config(&layout),
                    clock.clone(),
                    world.clone(),
                )
                .expect("sim hub");
                (Box::new(hub), Device::Sim(world))
            }
            Kind::Ch347 => {
                let mut cfg = Ch347HubConfig::default_for(SENSORS, TriggerMode::Broadcast);
                cfg.pace = true;
                cfg.reconnect_s = 5.0;
                let mut chip = Ch347Emulator::new();
                let now = clock.clone();
                let boards = Boards::attach(
                    &mut chip,
                    cameras(),
                    &cfg.cs,
                    Arc::new(move || now.now_us()),
                );
                let port = EmulatedPort::new(chip);
                let reopen = port.clone();
                let usb = port.open().expect("the emulated chip is plugged in");
                let hub = Ch347Hub::open(Ch347::new(usb), cfg, clock.clone())
                    .expect("hub opens")
                    .with_reopen(Box::new(move || reopen.open()));
                (Box::new(hub), Device::Ch347 { boards, port })
            }
            Kind::Cdc => {
                let link = std::env::temp_dir()
                    .join(format!("gelgrip-conformance-{name}-{}", std::process::id()));
                let _ = std::fs::remove_file(&link);
                let emulator = RunningHub::serve(
                    &link,
                    cameras(),
                    HubEmulatorConfig {
                        usb: UsbSpeed::High,
                        ring_capacity: CDC_RING_SETS,
                        ..HubEmulatorConfig::default()
                    },
                )
                .expect("the hub emulator serves");
                let prediction = SimHub::new(
                    &layout,
                    TriggerMode::Broadcast,
                    sim_config(&layout),
                    clock.clone(),
                )
                .expect("sim hub")
                .describe()
                .prediction;
                let hub = CdcHub::open(
                    CdcHubConfig {
                        port: link.display().to_string(),
                        sensors: SENSORS,
                        trigger: TriggerMode::Broadcast,
                        reconnect_s: 5.0,
                        prediction,
                        cpu_clock: None,
                    },
                    clock.clone(),
                )
                .expect("handshake and clock sync");
                (Box::new(hub), Device::Cdc(Arc::new(emulator), link))
            }
        };
        let acq = Acquisition::new(
            hub,
            Gate::new(SENSORS, LIMITS).without_exclusion(),
            clock.clone(),
            0,
        );
        Self {
            kind,
            acq,
            device,
            clock,
        }
    }

    /// Whether the device keeps sets across an unplug (the CDC hub's ring).
    pub fn buffers_sets(&self) -> bool {
        self.kind == Kind::Cdc
    }

    /// Give board `board` `faults` from now on (the simulator's equivalents: a frame
    /// corrupted with probability 1/n for "every n-th").
    pub fn set_faults(&self, board: usize, faults: BoardFaults) {
        match &self.device {
            Device::Sim(world) => {
                let sim = SensorFaults {
                    capture_delay_us: faults.capture_delay_us,
                    corrupt_rate: match faults.corrupt_every {
                        0 => 0.0,
                        n => 1.0 / n as f64,
                    },
                    dead: faults.dead,
                    ..SensorFaults::default()
                };
                world.lock().expect("world").inject_faults(board, Some(sim));
            }
            Device::Ch347 { boards, .. } => boards.set_faults(board, faults),
            Device::Cdc(hub, _) => hub.set_faults(board, faults),
        }
    }

    /// Unplug the device for `outage` (returns at once; it comes back by itself).
    pub fn unplug(&self, outage: Duration) {
        match &self.device {
            Device::Sim(world) => {
                let until = self.clock.now_us() + outage.as_micros() as u64;
                world.lock().expect("world").unplug_hub(until);
            }
            Device::Ch347 { port, .. } => {
                port.unplug();
                let port = port.clone();
                std::thread::spawn(move || {
                    std::thread::sleep(outage);
                    port.plug();
                });
            }
            Device::Cdc(hub, _) => {
                let hub = hub.clone();
                std::thread::spawn(move || hub.unplug(outage).expect("the hub comes back"));
            }
        }
    }

    /// Step the loop for `seconds` of real time; the sets the gate emitted.
    pub async fn run_for(&mut self, seconds: f64) -> Vec<FrameSet> {
        let end = self.clock.now_us() + (seconds * 1e6) as u64;
        let mut sets = Vec::new();
        while self.clock.now_us() < end {
            let step = tokio::time::timeout(Duration::from_secs(3), self.acq.step())
                .await
                .unwrap_or_else(|_| panic!("{:?}: no hub event within 3 s", self.kind));
            match step {
                Ok(Some(set)) => sets.push(set),
                Ok(None) => {}
                Err(e) => panic!("{:?}: the transport failed: {e}", self.kind),
            }
        }
        sets
    }

    /// The gate's statistics.
    pub fn stats(&self) -> &GateStats {
        self.acq.gate().stats()
    }

    /// Whether `frame` is whole: the simulator's a complete JPEG, an emulated board's its
    /// own pattern.
    pub fn frame_is_whole(&self, frame: &Frame) -> bool {
        let jpeg = &frame.jpeg[..];
        match self.kind {
            Kind::Sim => jpeg.starts_with(&[0xFF, 0xD8]) && jpeg.ends_with(&[0xFF, 0xD9]),
            Kind::Ch347 | Kind::Cdc => {
                jpeg.len() == JPEG_BYTES && usize::from(jpeg[0]) == usize::from(frame.sensor.0)
            }
        }
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        if let Device::Cdc(_, link) = &self.device {
            let _ = std::fs::remove_file(link);
        }
    }
}
