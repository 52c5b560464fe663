//! This program's composition root as the benches' [`Rig`]: configs loaded with every
//! transport registered ([`wiring`]), hubs opened behind their gates, and runs wired by
//! [`Session`] in this process. It answers in the benches' error type (`anyhow`, as the
//! binary's commands do): the library's typed [`crate::Error`] travels inside it, and the
//! binary reads the exit code from that type.

use std::path::Path;
use std::sync::Arc;

use async_trait::async_trait;
use gelgrip_bench::rig::{Rig, RunEnd, StartedRun};
use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::clock::Clock;
use gelgrip_controller::config::AppConfig;
use gelgrip_controller::runtime::options::RunOptions;
use gelgrip_plugins::config::PipelineConfig;
use gelgrip_plugins::pipeline::SensorPipeline;
use tokio::sync::mpsc;

use crate::output::RunReport;
use crate::session::{Session, run_to_end};
use crate::{tactile, wiring};

/// The program's adapters, as the benches run them.
#[derive(Debug, Clone, Copy, Default)]
pub struct ProgramRig;

/// A run's report as the benches read it.
fn run_end(report: &RunReport) -> anyhow::Result<RunEnd> {
    Ok(RunEnd {
        report: serde_json::to_value(report)?,
        exit_code: report.end_reason.exit_code(),
    })
}

#[async_trait]
impl Rig for ProgramRig {
    fn load_config(&self, path: Option<&Path>) -> anyhow::Result<AppConfig> {
        Ok(wiring::load_config(path, &wiring::registry())?)
    }

    async fn open_acquisition(
        &self,
        config: &AppConfig,
        clock: Arc<dyn Clock>,
    ) -> anyhow::Result<Acquisition> {
        Ok(wiring::open_acquisition(config, &wiring::registry(), clock).await?)
    }

    async fn run_to_end(&self, options: &RunOptions) -> anyhow::Result<RunEnd> {
        run_end(&run_to_end(options).await?)
    }

    async fn start(&self, options: &RunOptions) -> anyhow::Result<StartedRun> {
        let session = Session::open(options).await?;
        let dashboard_url = session.dashboard_url().map(str::to_string);
        let world = session.world().cloned();
        let (events, rx) = mpsc::channel(1);
        let end = tokio::spawn(async move { run_end(&session.run(rx).await) });
        Ok(StartedRun {
            dashboard_url,
            world,
            events,
            end,
        })
    }

    fn sensor_pipelines(&self, config: &AppConfig) -> anyhow::Result<Vec<SensorPipeline>> {
        let pipeline = PipelineConfig::from_section(&config.pipeline, &config.layout)?;
        Ok((0..config.layout.sensors.len())
            .map(|i| tactile::sensor_pipeline(config, &pipeline, i).map(|(p, _)| p))
            .collect::<crate::Result<_>>()?)
    }
}
