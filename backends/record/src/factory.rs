//! The `replay` hub transport's factory: `[hub.replay] dir` (a recording made with
//! `run --record`) and `speed` (a factor of the recorded pace, or `max`). The recording's
//! gate limits become the `auto` limits, so a replay gates as the run did.

use std::path::PathBuf;

use serde::Deserialize;

use crate::format::Meta;
use crate::reader::Recording;
use crate::replay::{ReplayHub, Speed, prediction_for_limits};
use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::hub::{HubError, HubTransport};
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::registry::{HubFactory, OpenError, OpenRequest};

/// Opens recordings as hubs.
#[derive(Debug, Clone, Copy, Default)]
pub struct ReplayFactory;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReplay {
    dir: String,
    #[serde(default = "default_speed")]
    speed: String,
}

fn default_speed() -> String {
    "1".into()
}

/// A validated `[hub.replay]`.
struct ReplaySettings {
    dir: PathBuf,
    speed: Speed,
}

fn settings(section: &BackendSection) -> Result<ReplaySettings, ConfigError> {
    let check = &section.check;
    let p = |k: &str| format!("{}.{k}", section.prefix);
    let raw: RawReplay = check.parse_table(&section.prefix, &section.table)?;
    let speed = match raw.speed.as_str() {
        "max" => Speed::Max,
        s => match s.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 && v <= 1000.0 => Speed::Factor(v),
            _ => {
                return Err(check.invalid(&p("speed"), s, "\"max\" or a factor in (0, 1000]"));
            }
        },
    };
    Ok(ReplaySettings {
        dir: section.base_dir.join(&raw.dir),
        speed,
    })
}

fn config_error(detail: String) -> OpenError {
    OpenError::Hub(HubError::Config { detail })
}

impl HubFactory for ReplayFactory {
    fn name(&self) -> &'static str {
        "replay"
    }

    fn validate(&self, section: &BackendSection, _layout: &HandLayout) -> Result<(), ConfigError> {
        settings(section).map(|_| ())
    }

    fn open(&self, request: OpenRequest<'_>) -> Result<Box<dyn HubTransport>, OpenError> {
        let s = settings(request.section)?;
        let recording = Recording::open(&s.dir).map_err(|e| config_error(e.to_string()))?;
        let header = recording
            .header()
            .map_err(|e| config_error(e.to_string()))?;
        let Meta::Header {
            sensors,
            max_spread_us,
            max_age_us,
            ..
        } = header
        else {
            return Err(config_error("the recording has no header".into()));
        };
        if sensors.len() != request.layout.sensors.len() {
            return Err(config_error(format!(
                "{}: the recording has {} sensors, layout {} has {}",
                s.dir.display(),
                sensors.len(),
                request.layout.name,
                request.layout.sensors.len()
            )));
        }
        let hub = ReplayHub::open(
            &recording,
            s.speed,
            request.clock,
            request.trigger,
            prediction_for_limits(max_spread_us, max_age_us),
        )
        .map_err(|e| config_error(e.to_string()))?;
        Ok(Box::new(hub))
    }
}
