//! Serving the dashboard from a run: bind the `[http]` address (or `--http`), serve the web
//! crate's app on it, print the URL, and, as an observer of the runtime, publish each
//! pass's frames, state and depth maps.

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use anyhow::Context;

use gelgrip_controller::actuator::hardware_error_names;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::gripper::GripperHandle;
use gelgrip_controller::runtime::control::LoopCommand;
use gelgrip_controller::runtime::plant::phase_name;
use gelgrip_controller::runtime::ports::{Observer, ObserverError};
use gelgrip_controller::runtime::report::SetReport;
use gelgrip_web::live::{
    DepthImage, ExcludedView, FingerView, SensorView, ServoView, SimView, SyncView, TaskView,
};
use gelgrip_web::{AppState, Live, Snapshot};
use tokio::sync::mpsc;

/// Depth maps are copied for the images at most this often, µs.
const DEPTH_PERIOD_US: u64 = 200_000;

/// A served dashboard.
pub struct Dashboard {
    live: Arc<Live>,
    /// The address it listens on (the actual port when 0 was asked for).
    pub addr: SocketAddr,
    transport: String,
    calibration: String,
    last_depth_us: Option<u64>,
    tasks_available: Vec<String>,
    finger_ids: Vec<String>,
    /// Each sensor's frame age in the last gated set, ms (empty before any).
    frame_ages_ms: Vec<Option<f64>>,
    /// The simulator's controls as the page shows them (`None` off the simulator), kept
    /// up to date by the run's control handler.
    sim: SharedSimView,
}

/// The simulator's controls as the page shows them, shared between the control handler
/// that changes them and the dashboard that shows them.
pub type SharedSimView = Arc<Mutex<Option<SimView>>>;

/// `bind` must be loopback unless a token is configured (config or `GELGRIP_HTTP_TOKEN`).
pub fn check_bind(bind: SocketAddr, token: Option<&str>) -> anyhow::Result<()> {
    if bind.ip().is_loopback() || token.is_some_and(|t| !t.is_empty()) {
        return Ok(());
    }
    Err(crate::UsageError(format!(
        "refusing to serve the dashboard on {bind} without a token: set http.token or \
         GELGRIP_HTTP_TOKEN, or bind a loopback address"
    ))
    .into())
}

impl Dashboard {
    /// Bind `bind` and serve; `gripper` is the grasp API the page commands (`None`: the
    /// page only watches), `control` where its task and simulator requests go.
    pub async fn start(
        config: &AppConfig,
        bind: SocketAddr,
        gripper: Option<GripperHandle>,
        control: Option<mpsc::Sender<LoopCommand>>,
        transport: String,
        sim: SharedSimView,
    ) -> anyhow::Result<Self> {
        let has_control = control.is_some() && gripper.is_some();
        check_bind(bind, config.http.token.as_deref())?;
        let live = Live::new(config.layout.sensor_ids());
        let fingers = config.layout.finger_ids();
        let mut state = AppState::new(live.clone(), gripper, fingers);
        state.control = control;
        state.current_limit_ma = config.servos.current_limit_ma;
        if !bind.ip().is_loopback()
            && let Some(token) = config.http.token.clone()
        {
            state = state.with_token(token);
        }
        let listener = tokio::net::TcpListener::bind(bind)
            .await
            .with_context(|| format!("binding the dashboard to {bind}"))?;
        let addr = listener.local_addr()?;
        let app = gelgrip_web::app(state);
        tokio::spawn(async move {
            if let Err(e) = axum::serve(listener, app).await {
                tracing::error!("dashboard server: {e}");
            }
        });
        eprintln!("dashboard: http://{addr}/");
        Ok(Self {
            live,
            addr,
            transport,
            calibration: calibration_text(config),
            last_depth_us: None,
            finger_ids: config.layout.fingers.iter().map(|f| f.id.clone()).collect(),
            frame_ages_ms: Vec::new(),
            tasks_available: if has_control {
                crate::catalog::names(crate::catalog::Kind::Task)
            } else {
                Vec::new()
            },
            sim,
        })
    }

    /// Publish one pass: a gated set's frames (as the hub sent them), the state, and (at
    /// most every 200 ms) the depth maps.
    fn publish(&mut self, report: &SetReport<'_>) {
        if let Some(set) = report.set {
            let mut ages = vec![None; self.live.ids().len()];
            for (f, age_us) in set.frames.iter().zip(report.frame_ages_us()) {
                let i = usize::from(f.frame.sensor.0);
                self.live.publish_frame(i, f.frame.jpeg.clone());
                if let Some(slot) = ages.get_mut(i) {
                    *slot = Some(age_us as f64 / 1e3);
                }
            }
            self.frame_ages_ms = ages;
        }
        let ids = self.live.ids().to_vec();
        let gripper = report.gripper.as_ref();
        let fused = gripper.and_then(|g| g.fused);
        let sensors = ids
            .iter()
            .enumerate()
            .map(|(i, id)| {
                let r = fused.and_then(|f| f.sensors.get(i).copied().flatten());
                SensorView {
                    id: id.clone(),
                    ok: r.is_some(),
                    in_contact: r.is_some_and(|r| r.in_contact),
                    area_mm2: r.map_or(0.0, |r| r.area_mm2),
                    max_depth_mm: r.map_or(0.0, |r| r.max_depth_mm),
                    force_n: r.map_or(0.0, |r| r.force_n),
                    deformation_mm3: r.map_or(0.0, |r| r.volume_mm3),
                    frame_age_ms: self.frame_ages_ms.get(i).copied().flatten(),
                    excluded: report.gate.excluded.iter().any(|e| e.sensor == i),
                }
            })
            .collect();
        let fingers = gripper.map_or_else(Vec::new, |g| {
            g.fingers
                .iter()
                .zip(&self.finger_ids)
                .map(|(f, id)| FingerView {
                    id: id.clone(),
                    phase: phase_name(f.phase).to_string(),
                    force_n: f.force_n,
                    target_force_n: f.target_force_n,
                })
                .collect()
        });
        let servos = gripper.map_or_else(Vec::new, |g| {
            g.servos
                .iter()
                .zip(&self.finger_ids)
                .map(|(s, id)| ServoView {
                    finger: id.clone(),
                    position_deg: s.position_deg,
                    current_ma: s.current_ma,
                    temperature_c: s.temperature_c,
                    errors: hardware_error_names(s.hardware_error)
                        .into_iter()
                        .map(str::to_string)
                        .collect(),
                })
                .collect()
        });
        let stats = report.gate;
        self.live.publish(Snapshot {
            t_s: report.t_s,
            transport: self.transport.clone(),
            sensors,
            fingers,
            servos,
            sync: SyncView {
                sets: stats.sets,
                set_rate_hz: stats.set_rate_hz(),
                spread_us_p99: stats.spread_us_p99(),
                spread_histogram_us: stats.spread_buckets(),
                drops: stats.drops,
                sets_rejected: stats.sets_rejected,
                loop_latency_ms_p99: gripper.and_then(|g| g.latencies.loop_p99),
                excluded_sensors: stats
                    .excluded
                    .iter()
                    .map(|e| ExcludedView {
                        sensor: ids.get(e.sensor).cloned().unwrap_or_default(),
                        reason: e.reason.key().to_string(),
                        since_s: report.t_s
                            - report.now_us.saturating_sub(e.since_host_us) as f64 / 1e6,
                    })
                    .collect(),
            },
            calibration: self.calibration.clone(),
            task: gripper.and_then(|g| g.task.as_ref()).map(|t| TaskView {
                name: t.name.clone(),
                stage: t.stage.clone(),
                running: t.running,
                outcome: t.outcome.clone(),
            }),
            tasks_available: self.tasks_available.clone(),
            sim: self.sim.lock().ok().and_then(|s| s.clone()),
        });
        let now_us = report.now_us;
        let due = self
            .last_depth_us
            .is_none_or(|last| now_us.saturating_sub(last) >= DEPTH_PERIOD_US);
        if due && let Some(g) = gripper {
            self.last_depth_us = Some(now_us);
            for i in 0..ids.len() {
                if let Some(w) = g.depth_window(i) {
                    self.live.publish_depth(
                        i,
                        DepthImage {
                            width: w.width,
                            height: w.height,
                            depth_mm: w.depth_mm,
                            contact_mm: w.contact_mm,
                        },
                    );
                }
            }
        }
    }
}

impl Observer for Dashboard {
    /// Never fails and never waits: the page's channels keep only the latest state and
    /// frames, so a slow browser drops what it could not take.
    fn observe(&mut self, report: &SetReport<'_>) -> Result<(), ObserverError> {
        self.publish(report);
        Ok(())
    }
}

/// How the sensors are calibrated, as the pipelines decide it (`tactile::sensor_model`): a
/// sensor with a `model` file uses it; the others self-calibrate on simulated presses.
fn calibration_text(config: &AppConfig) -> String {
    let sensors = config.layout.sensors.len();
    let from_files =
        gelgrip_plugins::config::PipelineConfig::from_section(&config.pipeline, &config.layout)
            .map_or(0, |p| {
                p.sensors.iter().filter(|s| s.model.is_some()).count()
            });
    match from_files {
        0 => "self-calibrated LUT per sensor (simulated presses, cached)".into(),
        n if n == sensors => "model files per sensor ([pipeline] model)".into(),
        n => format!(
            "{n} of {sensors} sensors from model files, the others self-calibrated on simulated presses"
        ),
    }
}
