//! The application configuration: TOML parsed into private raw structs, then validated into
//! domain types. Every error names the file, the field and what is allowed.
//!
//! Relative paths resolve against the directory of the file that contains them. The
//! transport-specific section `[hub.<transport>]` is handed, unparsed, to that transport's
//! factory, which validates it into its own types (see [`crate::registry`]).

mod error;
mod files;
mod grasp;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Deserialize;

pub use error::{ConfigError, FieldCheck};
pub use files::{CapturingFiles, DiskFiles, EmbeddedFiles, FileSource, MemoryFiles};

use crate::hub::TriggerMode;
use crate::layout::HandLayout;
use crate::registry::TransportRegistry;

/// A limit that is either derived from the bus model (`"auto"`) or fixed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Limit<T> {
    /// Derived from the transport's bus model.
    Auto,
    /// Set by the user.
    Fixed(T),
}

/// Default `[gate] queue_size`: a quarter second of frames at 30 Hz.
pub const DEFAULT_QUEUE_SIZE: usize = 8;

/// Which gate policy groups frames into sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GatePolicy {
    /// Group by trigger sequence.
    Trigger,
    /// Match by capture time (hubs without a shared trigger).
    Approximate,
    /// Each sensor's latest frame once per trigger period, unmatched: the unsynchronized
    /// baseline, for comparison.
    Latest,
}

/// `[gate]`.
#[derive(Debug, Clone, PartialEq)]
pub struct GateSettings {
    /// Grouping policy.
    pub policy: GatePolicy,
    /// Largest capture spread of an emitted set, in µs.
    pub max_spread_us: Limit<u32>,
    /// Largest age of an emitted set, in µs (configured in ms).
    pub max_age_us: Limit<u64>,
    /// `approximate`: frames held per sensor while they wait for partners.
    pub queue_size: usize,
    /// `trigger`: leave out of the sets a sensor that keeps failing the window, so the
    /// rest go on (`false`: refuse every set it fails, as a strict gate).
    pub exclude_failing_sensors: bool,
}

/// `[servos]`: the finger servo bus.
#[derive(Debug, Clone, PartialEq)]
pub struct ServoSettings {
    /// `sim` or `dynamixel`.
    pub bus: String,
    /// Serial port of the servo bus.
    pub port: String,
    /// Baud rate.
    pub baud: u32,
    /// Servo ids, one per finger.
    pub ids: Vec<u8>,
    /// Current Limit written to every servo, and the cap on every goal current, mA.
    pub current_limit_ma: f64,
    /// `[servos.sim]`, unparsed: the simulated bus validates it (fault injection).
    pub sim: toml::Table,
}

/// `[http]`.
#[derive(Debug, Clone, PartialEq)]
pub struct HttpSettings {
    /// Address the dashboard binds.
    pub bind: SocketAddr,
    /// Access token (required for a non-loopback bind).
    pub token: Option<String>,
}

/// The `[hub.<transport>]` section, for the transport's factory to validate.
#[derive(Debug, Clone)]
pub struct BackendSection {
    /// Builds errors naming the config file.
    pub check: FieldCheck,
    /// `hub.sim`, `hub.cdc`, …
    pub prefix: String,
    /// The raw table (empty when absent).
    pub table: toml::Table,
    /// Directory relative paths resolve against.
    pub base_dir: PathBuf,
    /// Where to read referenced files.
    pub files: Arc<dyn FileSource>,
}

/// `[hub]`.
#[derive(Debug, Clone)]
pub struct HubSettings {
    /// Transport name, chosen from the registry.
    pub transport: String,
    /// Broadcast or sequential trigger.
    pub trigger: TriggerMode,
    /// Sequence number of the first trigger (u32; set near the wrap to test it).
    pub first_trigger_seq: u32,
    /// The transport's own section.
    pub section: BackendSection,
}

/// A validated configuration.
#[derive(Debug, Clone)]
pub struct AppConfig {
    /// The file it came from (or `<embedded>/…`).
    pub file: String,
    /// The hand.
    pub layout: HandLayout,
    /// The hub.
    pub hub: HubSettings,
    /// The sync gate.
    pub gate: GateSettings,
    /// The servos.
    pub servos: ServoSettings,
    /// The dashboard.
    pub http: HttpSettings,
    /// `[pipeline]`: the tactile pipeline's stage choices, validated by the sensing plugins.
    pub pipeline: BackendSection,
    /// `[record]`: how `--record` writes (segment size, flush and fsync policy), validated
    /// by the recorder.
    pub record: BackendSection,
    /// `[ros]`: publishing to ROS 2 over Zenoh (`gelgrip run --ros`), validated by the
    /// program's ROS module.
    pub ros: BackendSection,
    /// `[grasp]`: how a grasp finds and keeps its force.
    pub grasp: crate::grasp::GraspSettings,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConfig {
    version: i64,
    layout: String,
    #[serde(default)]
    hub: RawHub,
    #[serde(default)]
    gate: RawGate,
    #[serde(default)]
    servos: RawServos,
    #[serde(default)]
    http: RawHttp,
    #[serde(default)]
    pipeline: toml::Table,
    #[serde(default)]
    record: toml::Table,
    #[serde(default)]
    ros: toml::Table,
    #[serde(default)]
    grasp: grasp::RawGrasp,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawHub {
    transport: String,
    trigger: String,
    first_trigger_seq: u32,
    sim: Option<toml::Table>,
    cdc: Option<toml::Table>,
    ch347: Option<toml::Table>,
    replay: Option<toml::Table>,
}

impl Default for RawHub {
    fn default() -> Self {
        Self {
            transport: "sim".into(),
            trigger: "broadcast".into(),
            first_trigger_seq: 0,
            sim: None,
            cdc: None,
            ch347: None,
            replay: None,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawGate {
    policy: String,
    max_spread_us: toml::Value,
    max_age_ms: toml::Value,
    queue_size: f64,
    exclude_failing_sensors: bool,
}

impl Default for RawGate {
    fn default() -> Self {
        Self {
            policy: "trigger".into(),
            max_spread_us: toml::Value::String("auto".into()),
            max_age_ms: toml::Value::String("auto".into()),
            queue_size: DEFAULT_QUEUE_SIZE as f64,
            exclude_failing_sensors: true,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawServos {
    bus: String,
    port: String,
    baud: u32,
    ids: Vec<u8>,
    current_limit_ma: f64,
    sim: toml::Table,
}

impl Default for RawServos {
    fn default() -> Self {
        Self {
            bus: "sim".into(),
            port: "/dev/ttyUSB0".into(),
            baud: 1_000_000,
            ids: vec![1, 2, 3],
            current_limit_ma: 1000.0,
            sim: toml::Table::new(),
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, default)]
struct RawHttp {
    bind: String,
    token: String,
}

impl Default for RawHttp {
    fn default() -> Self {
        Self {
            bind: "127.0.0.1:8080".into(),
            token: String::new(),
        }
    }
}

/// Baud rates an XM430 accepts (Baud Rate register 8).
pub const DYNAMIXEL_BAUDS: [u32; 8] = [
    9_600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000,
];

/// Environment variable that supplies the HTTP token when the config leaves it empty.
pub const HTTP_TOKEN_ENV: &str = "GELGRIP_HTTP_TOKEN";

impl AppConfig {
    /// Load and validate `path` through `files`; transport names are checked against
    /// `registry`, which also validates the transport's own section.
    pub fn load(
        path: &Path,
        files: Arc<dyn FileSource>,
        registry: &TransportRegistry,
    ) -> Result<Self, ConfigError> {
        let text = files.read(path)?;
        let file = path.display().to_string();
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::from_text(&file, &text, &base_dir, files, registry)
    }

    /// Validate config `text`, naming it `file` in errors.
    pub fn from_text(
        file: &str,
        text: &str,
        base_dir: &Path,
        files: Arc<dyn FileSource>,
        registry: &TransportRegistry,
    ) -> Result<Self, ConfigError> {
        let check = FieldCheck::new(file);
        let raw: RawConfig = check.parse(text)?;
        check.version(raw.version)?;
        let layout_path = base_dir.join(&raw.layout);
        let layout_text = files.read(&layout_path).map_err(|e| match e {
            ConfigError::Io { cause, .. } => ConfigError::Path {
                file: file.to_string(),
                key: "layout".into(),
                written: raw.layout.clone(),
                resolved: layout_path.display().to_string(),
                cause,
            },
            other => other,
        })?;
        let layout = HandLayout::from_toml(&layout_path.display().to_string(), &layout_text)?;
        let pipeline = BackendSection {
            check: check.clone(),
            prefix: "pipeline".into(),
            table: raw.pipeline,
            base_dir: base_dir.to_path_buf(),
            files: files.clone(),
        };
        let record = BackendSection {
            check: check.clone(),
            prefix: "record".into(),
            table: raw.record,
            base_dir: base_dir.to_path_buf(),
            files: files.clone(),
        };
        let ros = BackendSection {
            check: check.clone(),
            prefix: "ros".into(),
            table: raw.ros,
            base_dir: base_dir.to_path_buf(),
            files: files.clone(),
        };
        let servos = validate_servos(&check, raw.servos)?;
        let grasp = grasp::validate_grasp(&check, raw.grasp, &layout, servos.current_limit_ma)?;
        let hub = validate_hub(&check, raw.hub, base_dir, files, registry)?;
        registry.validate(&hub.transport, &hub.section, &layout)?;
        Ok(Self {
            file: file.to_string(),
            layout,
            hub,
            gate: validate_gate(&check, raw.gate)?,
            servos,
            grasp,
            http: validate_http(&check, raw.http)?,
            pipeline,
            record,
            ros,
        })
    }
}

fn validate_hub(
    check: &FieldCheck,
    raw: RawHub,
    base_dir: &Path,
    files: Arc<dyn FileSource>,
    registry: &TransportRegistry,
) -> Result<HubSettings, ConfigError> {
    registry.check_name(check, &raw.transport)?;
    let trigger = match raw.trigger.as_str() {
        "broadcast" => TriggerMode::Broadcast,
        "sequential" => TriggerMode::Sequential,
        other => return Err(check.invalid("hub.trigger", other, "broadcast | sequential")),
    };
    let table = match raw.transport.as_str() {
        "sim" => raw.sim,
        "cdc" => raw.cdc,
        "ch347" => raw.ch347,
        "replay" => raw.replay,
        _ => None,
    }
    .unwrap_or_default();
    Ok(HubSettings {
        section: BackendSection {
            check: check.clone(),
            prefix: format!("hub.{}", raw.transport),
            table,
            base_dir: base_dir.to_path_buf(),
            files,
        },
        transport: raw.transport,
        trigger,
        first_trigger_seq: raw.first_trigger_seq,
    })
}

fn limit(
    check: &FieldCheck,
    field: &str,
    value: &toml::Value,
    min: f64,
    max: f64,
) -> Result<Limit<f64>, ConfigError> {
    match value {
        toml::Value::String(s) if s == "auto" => Ok(Limit::Auto),
        toml::Value::Integer(i) => Ok(Limit::Fixed(check.range(field, *i as f64, min, max)?)),
        toml::Value::Float(f) => Ok(Limit::Fixed(check.range(field, *f, min, max)?)),
        other => Err(check.invalid(
            field,
            other,
            &format!("\"auto\" or a number in [{min}, {max}]"),
        )),
    }
}

fn validate_gate(check: &FieldCheck, raw: RawGate) -> Result<GateSettings, ConfigError> {
    let policy = match raw.policy.as_str() {
        "trigger" => GatePolicy::Trigger,
        "approximate" => GatePolicy::Approximate,
        "latest" => GatePolicy::Latest,
        other => {
            return Err(check.invalid("gate.policy", other, "trigger | approximate | latest"));
        }
    };
    let queue_size = check.range("gate.queue_size", raw.queue_size, 2.0, 1000.0)?;
    if queue_size.fract() != 0.0 {
        return Err(check.invalid("gate.queue_size", raw.queue_size, "a whole number"));
    }
    let spread = limit(check, "gate.max_spread_us", &raw.max_spread_us, 1.0, 1e6)?;
    let age = limit(check, "gate.max_age_ms", &raw.max_age_ms, 0.1, 60_000.0)?;
    Ok(GateSettings {
        policy,
        max_spread_us: match spread {
            Limit::Auto => Limit::Auto,
            Limit::Fixed(v) => Limit::Fixed(v.round() as u32),
        },
        max_age_us: match age {
            Limit::Auto => Limit::Auto,
            Limit::Fixed(v) => Limit::Fixed((v * 1000.0).round() as u64),
        },
        queue_size: queue_size as usize,
        exclude_failing_sensors: raw.exclude_failing_sensors,
    })
}

fn validate_servos(check: &FieldCheck, raw: RawServos) -> Result<ServoSettings, ConfigError> {
    match raw.bus.as_str() {
        "sim" | "dynamixel" => {}
        other => return Err(check.invalid("servos.bus", other, "sim | dynamixel")),
    }
    let current_limit_ma =
        check.range("servos.current_limit_ma", raw.current_limit_ma, 0.0, 3209.0)?;
    if !DYNAMIXEL_BAUDS.contains(&raw.baud) {
        return Err(check.invalid(
            "servos.baud",
            raw.baud,
            "one of 9600, 57600, 115200, 1000000, 2000000, 3000000, 4000000, 4500000",
        ));
    }
    if raw.ids.is_empty() || raw.ids.len() > 16 {
        return Err(check.invalid("servos.ids", format!("{:?}", raw.ids), "1 to 16 ids"));
    }
    for (i, id) in raw.ids.iter().enumerate() {
        if *id > 252 || raw.ids[..i].contains(id) {
            return Err(check.invalid(&format!("servos.ids[{i}]"), id, "a unique id in [0, 252]"));
        }
    }
    Ok(ServoSettings {
        bus: raw.bus,
        port: raw.port,
        baud: raw.baud,
        ids: raw.ids,
        current_limit_ma,
        sim: raw.sim,
    })
}

fn validate_http(check: &FieldCheck, raw: RawHttp) -> Result<HttpSettings, ConfigError> {
    let bind: SocketAddr = raw.bind.parse().map_err(|_| {
        check.invalid(
            "http.bind",
            &raw.bind,
            "an address:port such as 127.0.0.1:8080",
        )
    })?;
    let token = Some(raw.token)
        .filter(|t| !t.is_empty())
        .or_else(|| std::env::var(HTTP_TOKEN_ENV).ok().filter(|t| !t.is_empty()));
    if !bind.ip().is_loopback() && token.is_none() {
        return Err(check.invalid(
            "http.bind",
            bind,
            &format!(
                "a loopback address, or set http.token / {HTTP_TOKEN_ENV} for a non-loopback bind"
            ),
        ));
    }
    Ok(HttpSettings { bind, token })
}
