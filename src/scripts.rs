//! Finding a task script by name or path (`--task NAME|FILE`, the dashboard's
//! `POST /api/task`) and validating it for the run's layout and current limit. The script
//! itself runs in the runtime ([`gelgrip_controller::runtime::script_run`]).

use std::path::{Path, PathBuf};

use gelgrip_controller::config::{AppConfig, ConfigError};
use gelgrip_controller::task::TaskScript;

use crate::catalog::{self, Kind};

/// Read and validate the script `name` for `config`'s layout and current limit: a NAME is
/// `configs/tasks/NAME.toml` (on disk from the working directory, else among the embedded
/// configs); anything with a `/` or ending in `.toml` is a path.
pub fn load_script(name: &str, config: &AppConfig) -> crate::Result<TaskScript> {
    let io_error = |path: &Path, e: std::io::Error| {
        crate::UsageError(
            ConfigError::Io {
                file: path.display().to_string(),
                cause: e,
            }
            .to_string(),
        )
    };
    let (text, path) = if name.contains('/') || name.ends_with(".toml") {
        let path = PathBuf::from(name);
        match std::fs::read_to_string(&path) {
            Ok(text) => (text, path),
            Err(e) => return Err(io_error(&path, e).into()),
        }
    } else {
        match catalog::read(Kind::Task, name) {
            Ok(Some(found)) => found,
            Ok(None) => {
                return Err(crate::UsageError(format!(
                    "task `{name}`: no {} and no such built-in task; tasks: gentle-grasp, {}",
                    catalog::disk_path(Kind::Task, name).display(),
                    catalog::names(Kind::Task).join(", ")
                ))
                .into());
            }
            Err(e) => return Err(io_error(&catalog::disk_path(Kind::Task, name), e).into()),
        }
    };
    TaskScript::from_toml(
        &path.display().to_string(),
        &text,
        &config.layout,
        config.servos.current_limit_ma,
    )
    .map_err(|e| crate::UsageError(e.to_string()).into())
}
