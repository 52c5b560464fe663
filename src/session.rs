//! A run, wired from a config: the hub, the gate, the pipelines, the pilot, the servos, the
//! simulator when there is one, the recorder, the task log and the dashboard, assembled
//! into a [`Runtime`]; and, when it ends, the `run --json` report. `gelgrip run`, the
//! benches and the examples all run the gripper through this, in process.

use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::hub::HubDescription;
use gelgrip_controller::runtime::commanded::CommandedGripper;
use gelgrip_controller::runtime::fixed_close::FixedClose;
use gelgrip_controller::runtime::gentle_grasp::GentleGrasp;
use gelgrip_controller::runtime::outcome::EndReason;
use gelgrip_controller::runtime::pilot::Pilot;
use gelgrip_controller::runtime::plant::Plant;
use gelgrip_controller::runtime::ports::{GroundTruth, Sensing};
use gelgrip_controller::runtime::{Runtime, RuntimeEvent};
use gelgrip_sim::world::SharedWorld;
use tokio::sync::mpsc;

use crate::UsageError;
use crate::error::{Context, Error};
use crate::output::{RunReport, latency_ms};
use crate::scripts::load_script;
use crate::task_log::TaskLog;
use gelgrip_controller::gate::ExcludedSensor;
use gelgrip_record::observer::RunRecorder;

use crate::wiring;
use gelgrip_controller::gate::GateStats;
use gelgrip_sim::scene_report::SceneReport;
use gelgrip_sim::truth::SimTruth;

pub use gelgrip_controller::runtime::options::RunOptions;

/// The task's forces, speeds and timeouts, against what the configured hand can do (exit 2
/// in the CLI), before the hub and the servos are opened.
fn check_task(options: &RunOptions, config: &AppConfig) -> crate::Result<()> {
    match options.task.as_deref() {
        Some("gentle-grasp") if !config.layout.fingers.is_empty() => {
            let limit = config.servos.current_limit_ma;
            GentleGrasp::check(&config.layout, limit, &config.grasp, &options.grasp)
                .map_err(|e| UsageError(format!("gentle-grasp: {e}")))?;
        }
        Some("gentle-grasp") | None => {}
        Some(script) => {
            load_script(script, config)?;
        }
    }
    Ok(())
}

/// Whether the run drives the fingers through the grasp API when it has no task: with a
/// dashboard, when asked, or publishing to ROS 2; never while a sensor has no model (the
/// dashboard's grasp needs every sensor's pipeline; on a hardware hub without model files
/// the dashboard still serves the cameras, sync and servos).
fn drives_through_grasp_api(options: &RunOptions, config: &AppConfig) -> crate::Result<bool> {
    let unmodelled = crate::tactile::sensors_without_model(config)?;
    // A run that publishes to ROS 2 drives through the grasp API too (readings, servos).
    let ros_on = crate::optional::ros_enabled(config)?;
    if !options.headless && options.task.is_none() && !unmodelled.is_empty() {
        tracing::warn!(
            sensors = unmodelled.join(", "),
            "no gradient model file for these sensors on the {} hub: the dashboard serves \
             the cameras, sync and servos, without the grasp (docs/pipeline.md)",
            config.hub.transport
        );
    }
    Ok((!options.headless || options.grasp_api || ros_on) && unmodelled.is_empty())
}

/// Record the run into `dir`: the recorder taps `acq` (every hub event and gate decision).
fn start_recording(
    dir: &std::path::Path,
    config: &AppConfig,
    config_files: Vec<(String, String)>,
    acq: Acquisition,
) -> crate::Result<(Acquisition, RunRecorder)> {
    let description = acq.hub().describe().clone();
    let r = RunRecorder::start(dir, config, config_files, &description, acq.gate().limits())?;
    Ok((acq.with_tap(r.tap()), r))
}

/// The task CSV (`--log`, with the simulator's true forces when `sim_truth`) and the
/// recorder's per-set snapshots, as observers of `runtime`'s pilot.
fn log_and_record(
    runtime: &mut Runtime,
    options: &RunOptions,
    config: &AppConfig,
    sim_truth: bool,
    recorder: Option<&RunRecorder>,
) -> crate::Result<()> {
    if let Some(path) = &options.log
        && runtime.pilot().is_some()
    {
        runtime.observe(Box::new(TaskLog::create(path, &config.layout, sim_truth)?));
    }
    if let Some(r) = recorder {
        if let Some(d) = runtime.pilot_mut() {
            d.log_controller();
        }
        runtime.observe(r.snapshots());
    }
    Ok(())
}

/// The hub and gate a run acquires through, in the log.
fn log_acquiring(acq: &Acquisition) {
    let description = acq.hub().describe();
    tracing::info!(
        transport = description.transport,
        sensors = description.sensors,
        trigger = description.trigger.as_str(),
        max_spread_us = acq.gate().limits().max_spread_us,
        max_age_us = acq.gate().limits().max_age_us,
        "acquiring"
    );
}

/// A run, set up and ready.
pub struct Session {
    /// The runtime.
    pub runtime: Runtime,
    config: AppConfig,
    world: Option<SharedWorld>,
    recorder: Option<RunRecorder>,
    description: HubDescription,
    dashboard_url: Option<String>,
    clock_kind: ClockKind,
    duration_s: Option<f64>,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("runtime", &self.runtime)
            .finish_non_exhaustive()
    }
}

/// The pilot `options` ask for, on `bus`: the gentle grasp, a task script, the grasp API
/// (with a dashboard), or none (the fixed programme runs the servos); and the sensing it
/// senses through.
fn pilot(
    options: &RunOptions,
    config: &AppConfig,
    world: Option<&SharedWorld>,
    bus: Box<dyn gelgrip_controller::actuator::ServoBus>,
) -> crate::Result<(Pilot, Box<dyn Sensing>)> {
    let truth = world.map(|w| {
        Box::new(SimTruth::new(
            w.clone(),
            config.hub.transport == "sim",
            config.layout.sensors.len(),
        )) as Box<dyn GroundTruth>
    });
    let sensing: Box<dyn Sensing> = Box::new(crate::tactile::open(config)?);
    let plant = Plant::open(config.layout.clone(), bus, truth)?;
    let limit = config.servos.current_limit_ma;
    let pilot = match options.task.as_deref() {
        Some("gentle-grasp") => {
            let task = GentleGrasp::start(plant, limit, config.grasp, &options.grasp)
                .map_err(|e| UsageError(e.to_string()))?;
            tracing::info!(task = "gentle-grasp", "task running");
            Pilot::GentleGrasp(Box::new(task))
        }
        Some(name) => {
            let script = load_script(name, config)?;
            tracing::info!(
                task = script.name,
                stages = script.stages.len(),
                "task script"
            );
            let mut gripper = CommandedGripper::new(plant, limit, config.grasp);
            gripper
                .start_script(script)
                .map_err(|running| Error::TaskRunning { task: running })?;
            Pilot::Commanded {
                gripper: Box::new(gripper),
                script_ends_run: true,
            }
        }
        None => Pilot::Commanded {
            gripper: Box::new(CommandedGripper::new(plant, limit, config.grasp)),
            script_ends_run: false,
        },
    };
    Ok((pilot, sensing))
}

impl Session {
    /// Wire a run from `options`: load the config, open the hub, the servos and the
    /// simulator, build the pilot, start the recorder and the dashboard, and take the
    /// sensors' references (on a hardware hub).
    pub async fn open(options: &RunOptions) -> crate::Result<Self> {
        let registry = wiring::registry();
        let (config, config_files) =
            wiring::load_config_with_files(options.config.as_deref(), &registry)?;
        check_task(options, &config)?;
        let clock = options.clock.new_clock();
        let world = wiring::open_world(
            &config,
            options.scene.as_deref(),
            options.default_scene.as_deref(),
        )?;
        let registry = match &world {
            Some(w) => wiring::registry_with_world(w.clone()),
            None => registry,
        };
        let on_scene = world
            .as_ref()
            .and_then(|w| w.lock().ok().map(|w| w.scene().is_some()))
            .unwrap_or(false);
        let mut acq = wiring::open_acquisition(&config, &registry, clock.clone()).await?;
        let description = acq.hub().describe().clone();
        let recorder = match &options.record {
            Some(dir) => {
                let (tapped, r) = start_recording(dir, &config, config_files, acq)?;
                acq = tapped;
                Some(r)
            }
            None => None,
        };
        log_acquiring(&acq);
        let bus = wiring::open_servos(&config, world.as_ref(), clock.clone())?;
        let grasp_api = drives_through_grasp_api(options, &config)?;
        let mut runtime = Runtime::new(acq, clock.clone());
        match (options.task.as_deref(), bus) {
            (Some(_), Some(bus)) => {
                let (pilot, sensing) = pilot(options, &config, world.as_ref(), bus)?;
                runtime = runtime.with_pilot(pilot, sensing);
            }
            (Some(name), None) => {
                if name != "gentle-grasp" {
                    load_script(name, &config)?;
                }
                return Err(Error::Usage(UsageError(format!(
                    "task {name} needs finger servos; layout {} has no [[fingers]]",
                    config.layout.name
                ))));
            }
            (None, Some(bus)) if grasp_api => {
                let (pilot, sensing) = pilot(options, &config, world.as_ref(), bus)?;
                runtime = runtime.with_pilot(pilot, sensing);
            }
            (None, Some(bus)) => {
                let fixed = FixedClose::start(
                    bus,
                    &config.layout,
                    on_scene,
                    options.close_current_ma,
                    clock.now_us(),
                )
                .context("configuring the servos")?;
                runtime = runtime.with_fixed_close(fixed);
            }
            (None, None) => {}
        }
        let sim_truth = world.is_some() && config.hub.transport == "sim";
        log_and_record(&mut runtime, options, &config, sim_truth, recorder.as_ref())?;
        let dashboard_url = if options.headless {
            None
        } else {
            let clock = clock.clone();
            Some(
                crate::optional::serve_dashboard(
                    &mut runtime,
                    options,
                    &config,
                    world.clone(),
                    clock,
                    &description,
                )
                .await?,
            )
        };
        runtime.reference_sensors().await?;
        Ok(Self {
            runtime,
            config,
            world,
            recorder,
            description,
            dashboard_url,
            clock_kind: options.clock,
            duration_s: options.duration_s,
        })
    }

    /// The dashboard's URL (none when headless).
    pub fn dashboard_url(&self) -> Option<&str> {
        self.dashboard_url.as_deref()
    }

    /// The simulated world, on the simulated hub.
    pub fn world(&self) -> Option<&SharedWorld> {
        self.world.as_ref()
    }

    /// The run's config.
    pub fn config(&self) -> &AppConfig {
        &self.config
    }

    /// Run until `events` says stop, the duration passes, the task ends or a fault stops
    /// it; then bring the hardware to its safe state and report.
    pub async fn run(mut self, events: mpsc::Receiver<RuntimeEvent>) -> RunReport {
        // `--duration` counts from here, after the set-up (on a fresh machine the sensors'
        // self-calibration takes seconds), so a short run still acquires for its duration.
        self.runtime.begin(self.duration_s);
        let end = self.runtime.run(events).await;
        self.finish(end)
    }

    /// The sensors the gate has excluded, by id, with run time (`t_s`) of their exclusion.
    fn excluded_sensors(&self, stats: &GateStats) -> Vec<ExcludedSensor> {
        let origin = self.runtime.origin_us();
        stats
            .excluded
            .iter()
            .map(|e| ExcludedSensor {
                sensor: self
                    .config
                    .layout
                    .sensors
                    .get(e.sensor)
                    .map_or_else(|| format!("#{}", e.sensor), |s| s.id.to_string()),
                reason: e.reason.key().to_string(),
                since_s: e.since_host_us.saturating_sub(origin) as f64 / 1e6,
            })
            .collect()
    }

    /// Bring the hardware to its safe state after `end`, close the recording, and report.
    pub fn finish(mut self, end: EndReason) -> RunReport {
        let summary = self.runtime.finish(end);
        let mut faults: Vec<String> = summary
            .faults
            .faults()
            .iter()
            .map(ToString::to_string)
            .collect();
        let scene = self.world.as_ref().and_then(|w| {
            let w = w.lock().ok()?;
            SceneReport::of(&w, &self.config.layout)
        });
        drop(self.runtime.acquisition_mut().take_tap());
        let now = self.runtime.clock().now_us();
        let recording = self.recorder.take().map(|r| r.finish(now));
        if let Some(r) = &recording {
            if r.dropped_backpressure + r.dropped_io > 0 {
                tracing::warn!(
                    backpressure = r.dropped_backpressure,
                    io = r.dropped_io,
                    "the recorder dropped records"
                );
            }
            if let Some(e) = &r.error {
                faults.push(format!("recording: {e}"));
            }
        }
        let acq: &Acquisition = self.runtime.acquisition();
        let stats = acq.gate().stats();
        RunReport {
            recording,
            sensors: self.description.sensors,
            sets: stats.sets,
            set_rate_hz: stats.set_rate_hz(),
            spread_us_p99: stats.spread_us_p99(),
            faults,
            faults_omitted: summary.faults.omitted(),
            drops: stats.drops,
            sets_rejected: stats.sets_rejected,
            end_reason: summary.end_reason,
            transport: self.description.transport.clone(),
            trigger: self.description.trigger.as_str(),
            clock: match self.clock_kind {
                ClockKind::Real => "real",
                ClockKind::Virtual => "virtual",
            },
            elapsed_s: summary.elapsed_s,
            max_spread_us: acq.gate().limits().max_spread_us,
            max_age_us: acq.gate().limits().max_age_us,
            set_latency_ms_p50: latency_ms(stats, 0.5),
            set_latency_ms_p99: latency_ms(stats, 0.99),
            bus_latency_ms: self.description.prediction.set_latency_us / 1e3,
            bus_set_period_ms: self.description.prediction.set_period_us / 1e3,
            frames_received: stats.frames_in,
            frames_reused: stats.frames_reused,
            frames_in_sets: stats.frames_out,
            duplicate_sets: summary.duplicate_sets,
            excluded_sensors: self.excluded_sensors(stats),
            spread_histogram_us: stats.spread_buckets(),
            object: scene.as_ref().map(|s| s.object.clone()),
            crushed: scene.as_ref().map(|s| s.crushed),
            scene,
            servos: summary.servos.map(|s| s.to_vec()),
            dashboard_url: self.dashboard_url.clone(),
            task: summary.task,
            slip: summary.slip,
        }
    }
}

/// Run `options` to the end with no outside events (a task, a duration or a fault ends it):
/// what the benches and the examples do.
pub async fn run_to_end(options: &RunOptions) -> crate::Result<RunReport> {
    let session = Session::open(options).await?;
    let (_events, rx) = mpsc::channel(1);
    Ok(session.run(rx).await)
}
