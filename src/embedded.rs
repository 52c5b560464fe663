//! The configuration files compiled into the binary, so `gelgrip` runs with no files at all.

use gelgrip_controller::config::EmbeddedFiles;

/// Name of the default configuration among the embedded files.
pub const DEFAULT_CONFIG: &str = "gelgripper-sim.toml";

/// Every embedded file, by its path under `configs/`.
pub const FILES: EmbeddedFiles = EmbeddedFiles(&[
    (
        "gelgripper-sim.toml",
        include_str!("../configs/gelgripper-sim.toml"),
    ),
    (
        "gelgripper.toml",
        include_str!("../configs/gelgripper.toml"),
    ),
    (
        "layouts/three-finger.toml",
        include_str!("../configs/layouts/three-finger.toml"),
    ),
    (
        "layouts/five-finger.toml",
        include_str!("../configs/layouts/five-finger.toml"),
    ),
    (
        "tasks/screwdriver.toml",
        include_str!("../configs/tasks/screwdriver.toml"),
    ),
]);

/// Names of the embedded task scripts (`tasks/NAME.toml`).
pub const TASKS: &[&str] = &["screwdriver"];
