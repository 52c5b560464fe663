//! What the benches need of the program's composition root, handed to them by the binary:
//! a config loaded and checked with every transport the program registers, a hub opened
//! behind its gate, and a run of the gripper in this process (to its end, or started with
//! its dashboard and stopped later). Runs are read through their `run --json` report, the
//! contract users' scripts read too.

use std::path::Path;
use std::sync::Arc;

use async_trait::async_trait;
use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::clock::Clock;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::runtime::RuntimeEvent;
use gelgrip_controller::runtime::options::RunOptions;
use gelgrip_plugins::pipeline::SensorPipeline;
use tokio::sync::mpsc;

/// A run's end: its `run --json` report and the exit code `gelgrip run` gives for it.
#[derive(Debug, Clone, PartialEq)]
pub struct RunEnd {
    /// The `run --json` report.
    pub report: serde_json::Value,
    /// 0 for a run that ended as asked, else the code of its end reason (CONTRACTS.md).
    pub exit_code: u8,
}

/// A run started in this process.
#[derive(Debug)]
pub struct StartedRun {
    /// Its dashboard's URL (`None` when headless).
    pub dashboard_url: Option<String>,
    /// Its simulated world (`None` on real hardware): the virtual soak's storm runs in it.
    pub world: Option<gelgrip_sim::world::SharedWorld>,
    /// Where to send it events (`RuntimeEvent::Shutdown` ends it).
    pub events: mpsc::Sender<RuntimeEvent>,
    /// Its end, once it has ended (a join error if its task panicked).
    pub end: tokio::task::JoinHandle<anyhow::Result<RunEnd>>,
}

/// The composition root as the benches use it.
#[async_trait]
pub trait Rig: Send + Sync {
    /// The config at `path`, else the embedded simulated gripper's, checked with every
    /// transport the program registers.
    fn load_config(&self, path: Option<&Path>) -> anyhow::Result<AppConfig>;

    /// The hub `config` names, opened on `clock` with its sensors configured, behind the
    /// config's gate.
    async fn open_acquisition(
        &self,
        config: &AppConfig,
        clock: Arc<dyn Clock>,
    ) -> anyhow::Result<Acquisition>;

    /// Wire a run from `options` and run it to its end.
    async fn run_to_end(&self, options: &RunOptions) -> anyhow::Result<RunEnd>;

    /// Wire a run from `options` and start it on this runtime.
    async fn start(&self, options: &RunOptions) -> anyhow::Result<StartedRun>;

    /// The tactile pipelines a run of the simulated `config` senses with, one per sensor in
    /// layout order: each with its model (configured, else self-calibrated and cached) and
    /// referenced on untouched frames.
    fn sensor_pipelines(&self, config: &AppConfig) -> anyhow::Result<Vec<SensorPipeline>>;
}
