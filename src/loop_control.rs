//! The run loop's side of the dashboard's requests beyond the grasp API: start a task
//! script by name, and on the simulator inject sync faults or switch scenes. Each request
//! is answered at once: started, or a refusal that says why (unknown name, the gripper is
//! busy, not a simulated run).

use std::sync::Arc;

use gelgrip_controller::clock::Clock;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::runtime::control::{
    LoopRequest, Refusal, SensorFaultView, ServoFaultName, SharedSimView, SimFaults, SimView,
};
use gelgrip_controller::runtime::ports::{ControlHandler, PilotControl};
use gelgrip_sim::config::SensorFaults;
use gelgrip_sim::scene_spec::SceneSpec;
use gelgrip_sim::world::SharedWorld;

use crate::catalog::{self, Kind};
use crate::scripts::load_script;

/// A finger within this of its open position counts as open, degrees.
const OPEN_DEG: f64 = 5.0;

/// The run loop's request handler.
#[derive(Debug)]
pub struct LoopControl {
    view: SharedSimView,
    config: AppConfig,
    world: Option<SharedWorld>,
    scene: String,
    faults: Vec<SimFaults>,
    clock: Arc<dyn Clock>,
}

impl LoopControl {
    /// A handler for a run on `config`, whose simulator (if any) is `world`; it keeps
    /// `view` (what the page shows of the simulator's controls) up to date.
    pub fn new(
        config: &AppConfig,
        world: Option<SharedWorld>,
        clock: Arc<dyn Clock>,
        view: SharedSimView,
    ) -> Self {
        let scene = world
            .as_ref()
            .and_then(|w| w.lock().ok()?.scene().map(|s| s.name.clone()))
            .unwrap_or_else(|| "none".into());
        let control = Self {
            view,
            faults: vec![SimFaults::default(); config.layout.sensors.len()],
            config: config.clone(),
            world,
            scene,
            clock,
        };
        control.publish_view();
        control
    }

    fn publish_view(&self) {
        if let Ok(mut v) = self.view.lock() {
            *v = self.sim_view();
        }
    }
}

impl ControlHandler for LoopControl {
    fn handle(
        &mut self,
        request: LoopRequest,
        task: Option<&mut dyn PilotControl>,
    ) -> Result<(), Refusal> {
        let answer = match request {
            LoopRequest::Task { name } => self.start_task(&name, task),
            LoopRequest::SimFault { sensor, faults } => self.inject(sensor, faults),
            LoopRequest::SimScene { name } => self.switch_scene(&name, task),
            LoopRequest::SimUnplug { ms } => self.unplug(ms),
            LoopRequest::SimServoFault { finger, kind } => self.servo_fault(finger, kind),
        };
        self.publish_view();
        answer
    }
}

/// The refusal while task `running` drives the gripper.
fn busy(running: &str) -> Refusal {
    Refusal::Busy(format!(
        "task `{running}` is driving the gripper: stop it first"
    ))
}

impl LoopControl {
    fn start_task(
        &mut self,
        name: &str,
        task: Option<&mut dyn PilotControl>,
    ) -> Result<(), Refusal> {
        let Some(pilot) = task else {
            return Err(Refusal::Unavailable(
                "this run has no finger servos to run a task on".into(),
            ));
        };
        if let Some(running) = pilot.running_task() {
            return Err(busy(running));
        }
        let script =
            load_script(name, &self.config).map_err(|e| Refusal::Invalid(e.to_string()))?;
        pilot.start_script(script).map_err(|running| busy(&running))
    }

    fn world(&self) -> Result<&SharedWorld, Refusal> {
        self.world.as_ref().ok_or_else(|| {
            Refusal::Unavailable(format!(
                "simulator controls need the simulated hub; this run's hub is `{}`",
                self.config.hub.transport
            ))
        })
    }

    fn unplug(&mut self, ms: u32) -> Result<(), Refusal> {
        let until = self.clock.now_us() + u64::from(ms) * 1000;
        self.world()?
            .lock()
            .map_err(|_| Refusal::Unavailable("the simulator has failed".into()))?
            .unplug_hub(until);
        tracing::warn!(ms, "simulated hub unplugged");
        Ok(())
    }

    fn servo_fault(&mut self, finger: usize, kind: ServoFaultName) -> Result<(), Refusal> {
        if self.config.servos.bus != "sim" {
            return Err(Refusal::Unavailable(
                "servo faults are injected into simulated servos only".into(),
            ));
        }
        let mut w = self
            .world()?
            .lock()
            .map_err(|_| Refusal::Unavailable("the simulator has failed".into()))?;
        if finger >= w.fingers() {
            return Err(Refusal::Invalid(format!("no finger {finger}")));
        }
        w.change_motor(finger, |m| match kind {
            ServoFaultName::Overload => m.overloaded(),
            ServoFaultName::Overheating => m.with_temperature(95.0),
        });
        tracing::warn!(finger, ?kind, "simulated servo fault injected");
        Ok(())
    }

    fn inject(&mut self, sensor: usize, faults: SimFaults) -> Result<(), Refusal> {
        let world = self.world()?;
        let mut w = world
            .lock()
            .map_err(|_| Refusal::Unavailable("the simulator has failed".into()))?;
        w.inject_faults(
            sensor,
            faults.any().then_some(SensorFaults {
                capture_delay_us: faults.capture_delay_us,
                delivery_delay_us: faults.delivery_delay_us,
                drop_rate: faults.drop_rate,
                corrupt_rate: faults.corrupt_rate,
                dead: false,
                capture_jitter_us: faults.capture_jitter_us,
                clock_drift_ppm: faults.clock_drift_ppm,
            }),
        );
        drop(w);
        if let Some(slot) = self.faults.get_mut(sensor) {
            *slot = faults;
        }
        tracing::info!(sensor, ?faults, "simulator faults injected");
        Ok(())
    }

    fn switch_scene(
        &mut self,
        name: &str,
        task: Option<&mut dyn PilotControl>,
    ) -> Result<(), Refusal> {
        let world = self.world()?.clone();
        let spec = if name == "none" {
            None
        } else {
            let (text, path) = catalog::read(Kind::Scene, name)
                .map_err(|e| Refusal::Invalid(format!("scene `{name}`: {e}")))?
                .ok_or_else(|| {
                    Refusal::Invalid(format!(
                        "no scene `{name}`; scenes: none, {}",
                        catalog::names(Kind::Scene).join(", ")
                    ))
                })?;
            let spec =
                SceneSpec::from_toml(&path.display().to_string(), &text, &self.config.layout)
                    .map_err(|e| Refusal::Invalid(e.to_string()))?;
            Some(spec)
        };
        // The object appears where the fingers close: they must be open.
        if let Some(pilot) = task {
            if let Some(running) = pilot.running_task() {
                return Err(busy(running));
            }
            let closed: Vec<String> = pilot
                .servo_states()
                .iter()
                .zip(&self.config.layout.fingers)
                .filter(|(s, _)| s.position_deg > OPEN_DEG)
                .map(|(s, f)| format!("{} at {:.0}°", f.id, s.position_deg))
                .collect();
            if !closed.is_empty() {
                return Err(Refusal::Busy(format!(
                    "release the gripper first: a scene switches only with every finger \
                     open (within {OPEN_DEG}°); {}",
                    closed.join(", ")
                )));
            }
        }
        let mut w = world
            .lock()
            .map_err(|_| Refusal::Unavailable("the simulator has failed".into()))?;
        w.set_scene(spec);
        self.scene = name.to_string();
        tracing::info!(scene = name, "simulator scene switched");
        Ok(())
    }

    /// The simulator's controls for the page (`None` off the simulator).
    fn sim_view(&self) -> Option<SimView> {
        self.world.as_ref()?;
        let mut scenes = vec!["none".to_string()];
        scenes.extend(catalog::names(Kind::Scene));
        Some(SimView {
            scene: self.scene.clone(),
            scenes,
            faults: self
                .faults
                .iter()
                .enumerate()
                .filter(|(_, f)| f.any())
                .map(|(i, f)| SensorFaultView {
                    sensor: self.config.layout.sensors[i].id.to_string(),
                    faults: *f,
                })
                .collect(),
        })
    }
}
