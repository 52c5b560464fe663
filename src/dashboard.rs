//! Serving the dashboard from a run: bind the `[http]` address (or `--http`), serve the web
//! crate's app on it, print the URL, and publish each set's frames, state and depth maps.

use std::net::SocketAddr;
use std::sync::Arc;

use anyhow::Context;

use gelgrip_controller::actuator::hardware_error_names;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::gate::GateStats;
use gelgrip_controller::gripper::GripperHandle;
use gelgrip_web::control::LoopCommand;
use gelgrip_web::live::{DepthImage, FingerView, SensorView, ServoView, SimView, SyncView};
use gelgrip_web::{AppState, Live, Snapshot};
use tokio::sync::mpsc;

use crate::task_io::phase_name;
use crate::tasks::Task;

/// Depth maps are copied for the images at most this often, µs.
const DEPTH_PERIOD_US: u64 = 200_000;
/// Without sets, the state is still published this often, µs.
const QUIET_PERIOD_US: u64 = 100_000;

/// A served dashboard.
pub struct Dashboard {
    live: Arc<Live>,
    /// The address it listens on (the actual port when 0 was asked for).
    pub addr: SocketAddr,
    transport: String,
    calibration: String,
    last_depth_us: Option<u64>,
    last_state_us: Option<u64>,
    tasks_available: Vec<String>,
    /// The simulator's controls as the page shows them (`None` off the simulator).
    pub sim: Option<SimView>,
}

/// `bind` must be loopback unless a token is configured (config or `GELGRIP_HTTP_TOKEN`).
pub fn check_bind(bind: SocketAddr, token: Option<&str>) -> anyhow::Result<()> {
    if bind.ip().is_loopback() || token.is_some_and(|t| !t.is_empty()) {
        return Ok(());
    }
    Err(crate::cli::UsageError(format!(
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
    ) -> anyhow::Result<Self> {
        let has_control = control.is_some() && gripper.is_some();
        check_bind(bind, config.http.token.as_deref())?;
        let ids: Vec<String> = config
            .layout
            .sensors
            .iter()
            .map(|s| s.id.to_string())
            .collect();
        let live = Live::new(ids);
        let fingers: Vec<String> = config.layout.fingers.iter().map(|f| f.id.clone()).collect();
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
            last_state_us: None,
            tasks_available: if has_control {
                crate::catalog::names(crate::catalog::Kind::Task)
            } else {
                Vec::new()
            },
            sim: None,
        })
    }

    /// Publish one gated set: its frames (as the hub sent them), the state, and (at most
    /// every 200 ms) the depth maps.
    pub fn publish(
        &mut self,
        set: &FrameSet,
        task: Option<&Task>,
        stats: &GateStats,
        t_s: f64,
        now_us: u64,
    ) {
        for (i, f) in set.frames.iter().enumerate() {
            self.live.publish_frame(i, f.frame.jpeg.clone());
        }
        self.publish_state(task, stats, t_s, now_us);
    }

    /// Publish the state when no set has been published for 100 ms (the gate refuses sets,
    /// or the hub is silent): the page still sees the counters move and the fingers hold.
    pub fn publish_if_quiet(
        &mut self,
        task: Option<&Task>,
        stats: &GateStats,
        t_s: f64,
        now_us: u64,
    ) {
        if self
            .last_state_us
            .is_none_or(|last| now_us.saturating_sub(last) >= QUIET_PERIOD_US)
        {
            self.publish_state(task, stats, t_s, now_us);
        }
    }

    fn publish_state(&mut self, task: Option<&Task>, stats: &GateStats, t_s: f64, now_us: u64) {
        self.last_state_us = Some(now_us);
        let ids = self.live.ids().to_vec();
        let io = task.map(Task::io);
        let fused = io.and_then(|io| io.last_fused());
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
                }
            })
            .collect();
        let fingers = task.map_or_else(Vec::new, |t| {
            let ids = io
                .map(|io| {
                    io.layout
                        .fingers
                        .iter()
                        .map(|f| f.id.clone())
                        .collect::<Vec<_>>()
                })
                .unwrap_or_default();
            t.fingers()
                .into_iter()
                .zip(ids)
                .map(|((phase, force_n, target), id)| FingerView {
                    id,
                    phase: phase_name(phase).to_string(),
                    force_n,
                    target_force_n: target,
                })
                .collect()
        });
        let servos = io.map_or_else(Vec::new, |io| {
            io.states()
                .iter()
                .zip(&io.layout.fingers)
                .map(|(s, f)| ServoView {
                    finger: f.id.clone(),
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
        self.live.publish(Snapshot {
            t_s,
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
                loop_latency_ms_p99: io.and_then(|io| io.latencies().loop_p99),
            },
            calibration: self.calibration.clone(),
            task: task.and_then(Task::view),
            tasks_available: self.tasks_available.clone(),
            sim: self.sim.clone(),
        });
        let due = self
            .last_depth_us
            .is_none_or(|last| now_us.saturating_sub(last) >= DEPTH_PERIOD_US);
        if due && let Some(io) = io {
            self.last_depth_us = Some(now_us);
            for i in 0..ids.len() {
                if let Some((depth_mm, width, height, contact_mm)) = io.tactile().depth_window(i) {
                    self.live.publish_depth(
                        i,
                        DepthImage {
                            width,
                            height,
                            depth_mm,
                            contact_mm,
                        },
                    );
                }
            }
        }
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
