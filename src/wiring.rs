//! Wiring: the only place that knows the concrete adapters. It builds the transport registry,
//! loads configuration (from disk or the embedded defaults), opens the hub and assembles the
//! acquisition pipeline.

use std::path::Path;
use std::sync::Arc;

use crate::error::Context;

use gelgrip_cdc::factory::CdcFactory;
use gelgrip_ch347::factory::Ch347Factory;
use gelgrip_controller::acquire::{Acquisition, make_gate};
use gelgrip_controller::actuator::ServoBus;
use gelgrip_controller::clock::Clock;
use gelgrip_controller::config::{
    AppConfig, CapturingFiles, ConfigError, DiskFiles, FileSource, MemoryFiles,
};
use gelgrip_controller::hub::SensorSettings;
use gelgrip_controller::registry::{OpenRequest, TransportRegistry};
use gelgrip_dynamixel::driver::DynamixelBus;
use gelgrip_record::factory::ReplayFactory;
use gelgrip_sim::SimHubFactory;
use gelgrip_sim::board_cameras::SimCameraSource;
use gelgrip_sim::config::SimConfig;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::servo_bus::SimServoBus;
use gelgrip_sim::world::{SharedWorld, World};

use crate::embedded;

/// Every transport this build can open.
pub fn registry() -> TransportRegistry {
    let mut registry = TransportRegistry::new();
    registry.register(Box::new(SimHubFactory::default()));
    registry.register(Box::new(ch347(None)));
    registry.register(Box::new(CdcFactory::new(Some(thread_cpu_ns))));
    registry.register(Box::new(ReplayFactory));
    registry
}

/// The CH347 factory, its emulator's boards showing `world` (else the built-in presses).
fn ch347(world: Option<SharedWorld>) -> Ch347Factory {
    Ch347Factory::new(Some(thread_cpu_ns)).with_cameras(Arc::new(
        gelgrip_sim::press_requests::RequestedPresses::new(SimCameraSource::new(world)),
    ))
}

/// The same registry, with the simulated hub rendering `world`.
pub fn registry_with_world(world: SharedWorld) -> TransportRegistry {
    let mut registry = TransportRegistry::new();
    registry.register(Box::new(SimHubFactory::with_world(world.clone())));
    registry.register(Box::new(ch347(Some(world))));
    registry.register(Box::new(CdcFactory::new(Some(thread_cpu_ns))));
    registry.register(Box::new(ReplayFactory));
    registry
}

/// The simulated world a run needs, if any: with the sim hub, its configured scene (or
/// `scene_override`); with sim servos on another hub, empty space.
pub fn open_world(
    config: &AppConfig,
    scene_override: Option<&Path>,
    default_scene: Option<&str>,
) -> crate::Result<Option<SharedWorld>> {
    let sim_hub = config.hub.transport == "sim";
    if scene_override.is_some() && !sim_hub {
        return Err(crate::UsageError(format!(
            "--scene needs hub.transport = \"sim\" (this config uses \"{}\")",
            config.hub.transport
        ))
        .into());
    }
    let scene = match scene_override {
        Some(path) => {
            let text = gelgrip_controller::config::FileSource::read(&DiskFiles, path)?;
            Some(SceneSpec::from_toml(
                &path.display().to_string(),
                &text,
                &config.layout,
            )?)
        }
        None if sim_hub => {
            match SimConfig::from_section(&config.hub.section, &config.layout)?.scene {
                Some(scene) => Some(scene),
                None => match default_scene {
                    Some(name) => Some(embedded_scene(name, config)?),
                    None => None,
                },
            }
        }
        None => None,
    };
    if scene.is_some() && config.layout.fingers.is_empty() {
        return Err(crate::UsageError(format!(
            "a scene needs finger mechanics, and layout {} declares no [[fingers]]",
            config.layout.name
        ))
        .into());
    }
    if !sim_hub && config.servos.bus != "sim" {
        return Ok(None);
    }
    Ok(Some(World::new(&config.layout, scene).into_shared()))
}

/// The embedded scene `name` (`configs/scenes/NAME.toml`) for `config`'s layout, with its
/// fixture holding the object throughout: a scene's table drops away `release_after_s`
/// into the run (the hold test), but a run that opens on a default scene waits for someone
/// to press Grasp, whenever that is.
fn embedded_scene(name: &str, config: &AppConfig) -> crate::Result<SceneSpec> {
    let path = format!("scenes/{name}.toml");
    let text = gelgrip_controller::config::FileSource::read(&embedded::FILES, Path::new(&path))?;
    let mut scene =
        SceneSpec::from_toml(&format!("(embedded) configs/{path}"), &text, &config.layout)?;
    scene.release_after_s = None;
    Ok(scene)
}

/// The configured servo bus, or `None` when the layout has no fingers to drive.
pub fn open_servos(
    config: &AppConfig,
    world: Option<&SharedWorld>,
    clock: Arc<dyn Clock>,
) -> crate::Result<Option<Box<dyn ServoBus>>> {
    let s = &config.servos;
    match s.bus.as_str() {
        "dynamixel" => {
            let bus = DynamixelBus::open(&s.port, s.baud, &s.ids, s.current_limit_ma)
                .with_context(|| format!("opening the servo bus on {}", s.port))?;
            Ok(Some(Box::new(bus)))
        }
        _ => {
            let Some(world) = world.filter(|_| !config.layout.fingers.is_empty()) else {
                return Ok(None);
            };
            let faults = servo_faults(config)?;
            let bus = SimServoBus::new(world.clone(), clock, &s.ids, s.current_limit_ma)?
                .with_faults(faults);
            Ok(Some(Box::new(bus)))
        }
    }
}

/// Load `path`, or the embedded default configuration when `None`.
pub fn load_config(path: Option<&Path>, registry: &TransportRegistry) -> crate::Result<AppConfig> {
    load_config_with_files(path, registry).map(|(config, _)| config)
}

/// [`load_config`], also returning every file it read (path, text), the config first: what a
/// recording keeps so it can be replayed with the config it ran with.
pub fn load_config_with_files(
    path: Option<&Path>,
    registry: &TransportRegistry,
) -> crate::Result<(AppConfig, Vec<(String, String)>)> {
    let (path, source): (&Path, Arc<dyn FileSource>) = match path {
        Some(p) => (p, Arc::new(DiskFiles)),
        None => (
            Path::new(embedded::DEFAULT_CONFIG),
            Arc::new(embedded::FILES),
        ),
    };
    let capture = Arc::new(CapturingFiles::new(source));
    let config = AppConfig::load(path, capture.clone(), registry)?;
    let files = capture.files();
    let config = check_loaded(config)?;
    Ok((config, files))
}

/// Load a config from files held in memory (a recording's), the config at `path`.
pub fn load_config_from_memory(
    path: &Path,
    files: Vec<(String, String)>,
    registry: &TransportRegistry,
) -> crate::Result<AppConfig> {
    let config = AppConfig::load(path, Arc::new(MemoryFiles(files)), registry)?;
    check_loaded(config)
}

/// The checks beyond the config's own: the pipeline, the servo faults, the servo count.
fn check_loaded(config: AppConfig) -> crate::Result<AppConfig> {
    gelgrip_plugins::config::PipelineConfig::from_section(&config.pipeline, &config.layout)?;
    gelgrip_record::writer::RecorderOptions::from_section(&config.record)?;
    crate::optional::ros_enabled(&config)?;
    servo_faults(&config)?;
    check_servo_count(&config)?;
    Ok(config)
}

/// One servo per finger: a layout with fingers needs as many `servos.ids` (so
/// `check-config` catches a mismatch, not the first run).
fn check_servo_count(config: &AppConfig) -> crate::Result<()> {
    let fingers = config.layout.fingers.len();
    if fingers == 0 || config.servos.ids.len() == fingers {
        return Ok(());
    }
    Err(crate::UsageError(format!(
        "{}: servos.ids lists {} servos for the {} fingers of layout {}",
        config.file,
        config.servos.ids.len(),
        fingers,
        config.layout.name
    ))
    .into())
}

/// The simulated servo bus's scheduled faults (`[[servos.sim.faults]]`), validated.
fn servo_faults(
    config: &AppConfig,
) -> Result<Vec<gelgrip_sim::servo_fault_plan::ScheduledFault>, ConfigError> {
    let check = gelgrip_controller::config::FieldCheck::new(config.file.clone());
    gelgrip_sim::servo_fault_plan::parse(&check, &config.servos.sim, &config.servos.ids)
}

/// This thread's CPU time in ns (0 if the OS cannot tell).
pub fn thread_cpu_ns() -> u64 {
    cpu_time::ThreadTime::try_now()
        .map(|t| u64::try_from(t.as_duration().as_nanos()).unwrap_or(u64::MAX))
        .unwrap_or(0)
}

/// Open the configured hub and put a gate behind it.
pub async fn open_acquisition(
    config: &AppConfig,
    registry: &TransportRegistry,
    clock: Arc<dyn Clock>,
) -> crate::Result<Acquisition> {
    let request = OpenRequest {
        section: &config.hub.section,
        layout: &config.layout,
        trigger: config.hub.trigger,
        clock: clock.clone(),
    };
    let mut hub = registry.open(&config.hub.transport, request)?;
    let settings = vec![SensorSettings::default(); config.layout.sensors.len()];
    hub.configure_sensors(&settings)
        .await
        .context("configuring the sensor boards")?;
    let gate = make_gate(&config.gate, &config.layout, &hub.describe().prediction);
    Ok(
        Acquisition::new(hub, gate, clock, config.hub.first_trigger_seq)
            .with_cpu_clock(thread_cpu_ns),
    )
}
