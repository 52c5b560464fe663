//! The library's errors: one [`Error`] that every function of the composition root
//! returns, each variant the typed error of the part that failed, and its exit code for the
//! CLI ([`Error::exit_code`]: 2 for a usage or configuration error, 1 for a fault met while
//! running; CONTRACTS.md).

use gelgrip_controller::actuator::ServoError;
use gelgrip_controller::camera::CaptureError;
use gelgrip_controller::config::ConfigError;
use gelgrip_controller::hub::HubError;
use gelgrip_controller::registry::OpenError;
use gelgrip_controller::runtime::RuntimeError;
use gelgrip_plugins::calibrate::CalibrateError;
use gelgrip_plugins::calibrate::collect::CollectError;
use gelgrip_plugins::dataset::DatasetError;
use gelgrip_plugins::mlp::MlpError;
use gelgrip_plugins::model_file::ModelFileError;
use gelgrip_plugins::pipeline::PipelineError;
use gelgrip_record::format::RecordError;
use gelgrip_record::observer::RecordingStartError;
#[cfg(feature = "ros")]
use gelgrip_ros_bridge::BridgeError;
use gelgrip_sim::press_camera::SensorCameraError;
#[cfg(feature = "dashboard")]
use gelgrip_web::feed::ServeError;
use thiserror::Error;

pub use gelgrip_bench::args::UsageError;

/// What went wrong in the composition root, with the part's own typed error.
#[derive(Debug, Error)]
pub enum Error {
    /// A request that cannot be carried out as given.
    #[error(transparent)]
    Usage(#[from] UsageError),
    /// An invalid configuration file or section.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A hub transport that cannot be opened.
    #[error(transparent)]
    Open(#[from] OpenError),
    /// The hub failed.
    #[error(transparent)]
    Hub(#[from] HubError),
    /// A servo bus failed.
    #[error(transparent)]
    Servo(#[from] ServoError),
    /// The run loop failed.
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    /// The dashboard cannot be served.
    #[cfg(feature = "dashboard")]
    #[error(transparent)]
    Dashboard(#[from] ServeError),
    /// The ROS 2 bridge cannot start.
    #[cfg(feature = "ros")]
    #[error(transparent)]
    Bridge(#[from] BridgeError),
    /// The recording cannot start.
    #[error(transparent)]
    RecordingStart(#[from] RecordingStartError),
    /// A recording cannot be read.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// A sensor has no simulated camera.
    #[error(transparent)]
    SensorCamera(#[from] SensorCameraError),
    /// A camera gave no frame.
    #[error(transparent)]
    Capture(#[from] CaptureError),
    /// Simulated presses could not be collected.
    #[error(transparent)]
    Collect(#[from] CollectError),
    /// A press dataset cannot be read.
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// A model could not be trained or evaluated.
    #[error(transparent)]
    Calibrate(#[from] CalibrateError),
    /// A gradient model file cannot be read.
    #[error(transparent)]
    ModelFile(#[from] ModelFileError),
    /// An MLP model cannot be read or run.
    #[error(transparent)]
    Mlp(#[from] MlpError),
    /// A sensor's pipeline failed.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// A file could not be read or written.
    #[error("{what}: {source}")]
    Io {
        /// What was being done (creating the log X), or the file.
        what: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// Stored JSON that does not parse.
    #[error("{what}: {source}")]
    Json {
        /// What it is.
        what: String,
        /// The parser's error.
        source: serde_json::Error,
    },
    /// A recording that lacks what a replay needs.
    #[error("{0}")]
    Recording(String),
    /// A model file whose kind is not the one its sensor's gradient stage runs.
    #[error(
        "sensor {sensor}: model {path} is a {kind} model but the sensor's gradient stage is `{stage}`"
    )]
    ModelKind {
        /// The sensor's id.
        sensor: String,
        /// The model file.
        path: String,
        /// The file's kind (`lut`, `mlp`).
        kind: &'static str,
        /// The stage's kind.
        stage: &'static str,
    },
    /// A task was asked to start while another runs.
    #[error("task {task} already running")]
    TaskRunning {
        /// The task that runs.
        task: String,
    },
    /// No sensor at this index of the layout.
    #[error("sensor index out of range")]
    NoSensor {
        /// The index asked for.
        index: usize,
    },
    /// The failure, with what was being done.
    #[error("{context}")]
    Context {
        /// What was being done.
        context: String,
        /// The failure.
        #[source]
        source: Box<Error>,
    },
}

/// The library's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// The CLI's exit code for this error: 2 for a usage or configuration error, else 1.
    pub fn exit_code(&self) -> u8 {
        if self.is_usage() { 2 } else { 1 }
    }

    /// A usage or configuration error (the request or the config is wrong, not the run).
    pub fn is_usage(&self) -> bool {
        match self {
            Self::Usage(_) | Self::Config(_) => true,
            Self::Open(e) => matches!(e, OpenError::Config(_)),
            #[cfg(feature = "dashboard")]
            Self::Dashboard(e) => matches!(e, ServeError::OpenWithoutToken { .. }),
            #[cfg(feature = "ros")]
            Self::Bridge(e) => e.is_usage(),
            Self::RecordingStart(e) => matches!(e, RecordingStartError::Options(_)),
            Self::SensorCamera(e) => matches!(e, SensorCameraError::Config(_)),
            Self::Context { source, .. } => source.is_usage(),
            _ => false,
        }
    }

    /// An I/O error while doing `what` (a file's path, or what was being done to it).
    pub fn io(what: impl Into<String>, source: std::io::Error) -> Self {
        Self::Io {
            what: what.into(),
            source,
        }
    }
}

/// `.context(…)` for the library's results, as `anyhow` has for the binary's.
pub trait Context<T> {
    /// The error, with what was being done.
    fn context(self, context: impl Into<String>) -> Result<T>;
    /// The error, with what was being done (built only on failure).
    fn with_context<C: Into<String>>(self, context: impl FnOnce() -> C) -> Result<T>;
}

impl<T, E: Into<Error>> Context<T> for std::result::Result<T, E> {
    fn context(self, context: impl Into<String>) -> Result<T> {
        self.map_err(|e| Error::Context {
            context: context.into(),
            source: Box::new(e.into()),
        })
    }

    fn with_context<C: Into<String>>(self, context: impl FnOnce() -> C) -> Result<T> {
        self.map_err(|e| Error::Context {
            context: context().into(),
            source: Box::new(e.into()),
        })
    }
}
