//! Where configuration files come from: the disk, or the set embedded in the binary.

use std::path::{Path, PathBuf};

use super::ConfigError;

/// Reads configuration files by path.
pub trait FileSource: std::fmt::Debug + Send + Sync {
    /// The text of `path`.
    fn read(&self, path: &Path) -> Result<String, ConfigError>;
}

/// Files on disk.
#[derive(Debug, Clone, Copy, Default)]
pub struct DiskFiles;

impl FileSource for DiskFiles {
    fn read(&self, path: &Path) -> Result<String, ConfigError> {
        std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            file: path.display().to_string(),
            source,
        })
    }
}

/// Files compiled into the binary, by path relative to `configs/`.
#[derive(Debug, Clone, Copy)]
pub struct EmbeddedFiles(pub &'static [(&'static str, &'static str)]);

impl FileSource for EmbeddedFiles {
    fn read(&self, path: &Path) -> Result<String, ConfigError> {
        let wanted = normalize(path);
        self.0
            .iter()
            .find(|(name, _)| Path::new(name) == wanted)
            .map(|(_, text)| (*text).to_string())
            .ok_or_else(|| ConfigError::Io {
                file: format!("<embedded>/{}", path.display()),
                source: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "not among the embedded configs",
                ),
            })
    }
}

/// Drop `.` components and fold `..` so embedded paths compare plainly.
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}
