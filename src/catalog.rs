//! Named task scripts and scenes: `NAME` is `configs/{tasks,scenes}/NAME.toml` in the
//! working directory, else the copy embedded in the binary. The dashboard lists and starts
//! them by name; `--task NAME` uses the same lookup.

use std::path::{Path, PathBuf};

use crate::embedded;

/// A kind of named file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `configs/tasks`.
    Task,
    /// `configs/scenes`.
    Scene,
}

impl Kind {
    fn dir(self) -> &'static str {
        match self {
            Self::Task => "tasks",
            Self::Scene => "scenes",
        }
    }

    fn embedded(self) -> &'static [&'static str] {
        match self {
            Self::Task => embedded::TASKS,
            Self::Scene => embedded::SCENES,
        }
    }
}

/// Where `NAME` lives on disk.
pub fn disk_path(kind: Kind, name: &str) -> PathBuf {
    PathBuf::from(format!("configs/{}/{name}.toml", kind.dir()))
}

/// Every name of `kind`: the files on disk and the embedded ones, sorted, once each.
pub fn names(kind: Kind) -> Vec<String> {
    let mut out: Vec<String> = kind.embedded().iter().map(|s| s.to_string()).collect();
    if let Ok(dir) = std::fs::read_dir(Path::new("configs").join(kind.dir())) {
        for entry in dir.flatten() {
            let path = entry.path();
            if path.extension().is_some_and(|e| e == "toml")
                && let Some(stem) = path.file_stem().and_then(|s| s.to_str())
            {
                out.push(stem.to_string());
            }
        }
    }
    out.sort();
    out.dedup();
    out
}

/// The text of `NAME` and the path it came from (disk first, then embedded); `None` when
/// neither has it. A file that exists but cannot be read is an error.
pub fn read(kind: Kind, name: &str) -> std::io::Result<Option<(String, PathBuf)>> {
    let path = disk_path(kind, name);
    match std::fs::read_to_string(&path) {
        Ok(text) => Ok(Some((text, path))),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            use gelgrip_controller::config::FileSource;
            Ok(embedded::FILES
                .read(Path::new(&format!("{}/{name}.toml", kind.dir())))
                .ok()
                .map(|text| (text, path)))
        }
        Err(e) => Err(e),
    }
}
