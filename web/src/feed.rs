//! The dashboard's feed from a run: bind the `[http]` address (or `--http`), serve
//! [`crate::app`] on it, print the URL, and, as an observer of the runtime, publish each
//! pass's frames, state and depth maps. What the page shows beside the run's own report (the
//! task catalog's names, how the pipelines were calibrated) is handed in ([`FeedSetup`]).

use std::net::SocketAddr;
use std::sync::Arc;

use thiserror::Error;

use gelgrip_controller::actuator::{ServoState, hardware_error_names};
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::gripper::GripperHandle;
use gelgrip_controller::runtime::control::LoopCommand;
use gelgrip_controller::runtime::plant::phase_name;
use gelgrip_controller::runtime::ports::{Observer, ObserverError};
use gelgrip_controller::runtime::report::{GripperReport, SetReport};
use tokio::sync::mpsc;

use crate::live::{
    DepthImage, ExcludedView, FingerView, SensorView, ServoView, SlipView, SyncView, TaskView,
};
use crate::{AppState, Live, Snapshot};

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

pub use gelgrip_controller::runtime::control::SharedSimView;

/// Why the dashboard cannot be served.
#[derive(Debug, Error)]
pub enum ServeError {
    /// An address off loopback without a token (a usage error: exit code 2).
    #[error(
        "refusing to serve the dashboard on {bind} without a token: set http.token or \
         GELGRIP_HTTP_TOKEN, or bind a loopback address"
    )]
    OpenWithoutToken {
        /// The address asked for.
        bind: SocketAddr,
    },
    /// The address cannot be bound (in use, not this host's).
    #[error("binding the dashboard to {bind}")]
    Bind {
        /// The address asked for.
        bind: SocketAddr,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
}

/// `bind` must be loopback unless a token is configured (config or `GELGRIP_HTTP_TOKEN`).
pub fn check_bind(bind: SocketAddr, token: Option<&str>) -> Result<(), ServeError> {
    if bind.ip().is_loopback() || token.is_some_and(|t| !t.is_empty()) {
        return Ok(());
    }
    Err(ServeError::OpenWithoutToken { bind })
}

/// What the page shows that the run's per-set report does not carry, handed in by whoever
/// wires the run.
#[derive(Debug, Clone, Default)]
pub struct FeedSetup {
    /// The hub transport's name.
    pub transport: String,
    /// How the sensors are calibrated, in a line.
    pub calibration: String,
    /// The tasks the page may start (shown only when it commands the gripper).
    pub tasks: Vec<String>,
}

impl Dashboard {
    /// Bind `bind` and serve; `gripper` is the grasp API the page commands (`None`: the
    /// page only watches), `control` where its task and simulator requests go.
    pub async fn start(
        config: &AppConfig,
        bind: SocketAddr,
        gripper: Option<GripperHandle>,
        control: Option<mpsc::Sender<LoopCommand>>,
        setup: FeedSetup,
        sim: SharedSimView,
    ) -> Result<Self, ServeError> {
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
            .map_err(|source| ServeError::Bind { bind, source })?;
        let addr = listener
            .local_addr()
            .map_err(|source| ServeError::Bind { bind, source })?;
        let app = crate::app(state);
        tokio::spawn(async move {
            if let Err(e) = axum::serve(listener, app).await {
                tracing::error!("dashboard server: {e}");
            }
        });
        eprintln!("dashboard: http://{addr}/");
        Ok(Self {
            live,
            addr,
            transport: setup.transport,
            calibration: setup.calibration,
            last_depth_us: None,
            finger_ids: config.layout.fingers.iter().map(|f| f.id.clone()).collect(),
            frame_ages_ms: Vec::new(),
            tasks_available: if has_control { setup.tasks } else { Vec::new() },
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
        let gripper = report.gripper.as_ref();
        self.live.publish(Snapshot {
            t_s: report.t_s,
            transport: self.transport.clone(),
            sensors: self.sensor_views(report),
            fingers: gripper.map_or_else(Vec::new, |g| self.finger_views(g)),
            servos: report
                .servos
                .map_or_else(Vec::new, |s| self.servo_views(s.states)),
            sync: self.sync_view(report),
            calibration: self.calibration.clone(),
            task: gripper.and_then(|g| g.task.as_ref()).map(|t| TaskView {
                name: t.name.clone(),
                stage: t.stage.clone(),
                running: t.running,
                outcome: t.outcome.clone(),
            }),
            tasks_available: self.tasks_available.clone(),
            sim: self.sim.lock().ok().and_then(|s| s.clone()),
            slip_state: gripper
                .and_then(|g| g.fused)
                .and_then(|f| f.slip())
                .map(|s| s.state.as_str()),
            settled_force_n: gripper.and_then(|g| g.settled_force_n),
        });
        let now_us = report.now_us;
        let due = self
            .last_depth_us
            .is_none_or(|last| now_us.saturating_sub(last) >= DEPTH_PERIOD_US);
        if due && let Some(g) = gripper {
            self.last_depth_us = Some(now_us);
            self.publish_depth(g);
        }
    }

    /// Each sensor's reading in this pass (a sensor the set did not sense shows not ok).
    fn sensor_views(&self, report: &SetReport<'_>) -> Vec<SensorView> {
        let fused = report.gripper.as_ref().and_then(|g| g.fused);
        self.live
            .ids()
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
                    slip: r.and_then(|r| r.slip).map(SlipView::from),
                }
            })
            .collect()
    }

    /// Each finger's grasp phase and force.
    fn finger_views(&self, g: &GripperReport<'_>) -> Vec<FingerView> {
        g.fingers
            .iter()
            .zip(&self.finger_ids)
            .enumerate()
            .map(|(i, (f, id))| FingerView {
                id: id.clone(),
                phase: phase_name(f.phase).to_string(),
                force_n: f.force_n,
                target_force_n: f.target_force_n,
                slip_state: g
                    .fused
                    .and_then(|s| s.fingers.get(i))
                    .and_then(|c| c.slip)
                    .map(|s| s.state.as_str()),
            })
            .collect()
    }

    /// Each finger's servo, its hardware errors by name.
    fn servo_views(&self, states: &[ServoState]) -> Vec<ServoView> {
        states
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
    }

    /// The gate's statistics and the loop's latency.
    fn sync_view(&self, report: &SetReport<'_>) -> SyncView {
        let stats = report.gate;
        let ids = self.live.ids();
        SyncView {
            sets: stats.sets,
            set_rate_hz: stats.set_rate_hz(),
            spread_us_p99: stats.spread_us_p99(),
            spread_histogram_us: stats.spread_buckets(),
            frames_received: stats.frames_in,
            frames_in_sets: stats.frames_out,
            drops: stats.drops,
            sets_rejected: stats.sets_rejected,
            loop_latency_ms_p99: report.gripper.as_ref().and_then(|g| g.latencies.loop_p99),
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
        }
    }

    /// The depth maps, as the page draws them.
    fn publish_depth(&self, g: &GripperReport<'_>) {
        for i in 0..self.live.ids().len() {
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

impl Observer for Dashboard {
    /// Never fails and never waits: the page's channels keep only the latest state and
    /// frames, so a slow browser drops what it could not take.
    fn observe(&mut self, report: &SetReport<'_>) -> Result<(), ObserverError> {
        self.publish(report);
        Ok(())
    }
}
