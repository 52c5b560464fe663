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
        std::fs::read_to_string(path).map_err(|cause| ConfigError::Io {
            file: path.display().to_string(),
            cause,
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
                cause: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "not among the embedded configs",
                ),
            })
    }
}

/// Files held in memory (a recording's copy of the config it ran with), by path.
#[derive(Debug, Clone, Default)]
pub struct MemoryFiles(pub Vec<(String, String)>);

impl FileSource for MemoryFiles {
    fn read(&self, path: &Path) -> Result<String, ConfigError> {
        let wanted = normalize(path);
        self.0
            .iter()
            .find(|(name, _)| normalize(Path::new(name)) == wanted)
            .map(|(_, text)| text.clone())
            .ok_or_else(|| ConfigError::Io {
                file: path.display().to_string(),
                cause: std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "not among the recording's files",
                ),
            })
    }
}

/// Another source whose every successful read is kept (path, text), so a recording can
/// carry the exact files its config was built from.
#[derive(Debug)]
pub struct CapturingFiles {
    inner: std::sync::Arc<dyn FileSource>,
    read: std::sync::Mutex<Vec<(String, String)>>,
}

impl CapturingFiles {
    /// Capture what is read from `inner`.
    pub fn new(inner: std::sync::Arc<dyn FileSource>) -> Self {
        Self {
            inner,
            read: std::sync::Mutex::new(Vec::new()),
        }
    }

    /// The files read so far, in order, each once.
    pub fn files(&self) -> Vec<(String, String)> {
        self.read.lock().map(|r| r.clone()).unwrap_or_default()
    }
}

impl FileSource for CapturingFiles {
    fn read(&self, path: &Path) -> Result<String, ConfigError> {
        let text = self.inner.read(path)?;
        if let Ok(mut read) = self.read.lock() {
            let name = path.display().to_string();
            if !read.iter().any(|(n, _)| *n == name) {
                read.push((name, text.clone()));
            }
        }
        Ok(text)
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
