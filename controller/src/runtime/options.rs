//! What a program asks of a run: `gelgrip run`'s options without the command line. The
//! composition root (the `gelgrip` library's `session`) wires a run from them; the
//! benches, the tests and the examples build them too.

use std::net::SocketAddr;
use std::path::PathBuf;

use crate::clock::ClockKind;
use crate::runtime::gentle_grasp::GraspOptions;

/// How to run: `gelgrip run`'s options, without the command line.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// The config file (`None`: the embedded simulated gripper).
    pub config: Option<PathBuf>,
    /// A scene instead of the config's (simulated hub only).
    pub scene: Option<PathBuf>,
    /// An embedded scene's name (`configs/scenes/NAME.toml`) to use when neither `scene`
    /// nor the config names one (simulated hub only), its object held in place until
    /// grasped (the table never drops away): the dashboard run of the default config opens
    /// on the tennis ball.
    pub default_scene: Option<String>,
    /// Real or virtual time.
    pub clock: ClockKind,
    /// `gentle-grasp`, a task script's name or file, or none (the grasp API drives).
    pub task: Option<String>,
    /// The gentle grasp's options.
    pub grasp: GraspOptions,
    /// The task CSV.
    pub log: Option<PathBuf>,
    /// Record into this directory.
    pub record: Option<PathBuf>,
    /// No dashboard.
    pub headless: bool,
    /// Without a task, drive the fingers through the grasp API even when headless (what a
    /// program that embeds the runtime wants; with a dashboard it always does).
    pub grasp_api: bool,
    /// The dashboard's address (else the config's).
    pub http: Option<SocketAddr>,
    /// The fixed programme's closing current (headless on a scene, no task), mA.
    pub close_current_ma: f64,
    /// Run this long after the set-up, s (on the run's clock).
    pub duration_s: Option<f64>,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            config: None,
            scene: None,
            default_scene: None,
            clock: ClockKind::Real,
            task: None,
            grasp: GraspOptions {
                target_force: crate::grasp::TargetForce::default(),
                speed_deg_s: 15.0,
                timeout_s: 20.0,
                hold_s: 0.0,
                lift_rise_s: crate::runtime::gentle_grasp::LIFT_RISE_S,
            },
            log: None,
            record: None,
            headless: false,
            grasp_api: false,
            http: None,
            close_current_ma: 800.0,
            duration_s: None,
        }
    }
}
