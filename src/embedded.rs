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
    (
        "tasks/pick-and-release.toml",
        include_str!("../configs/tasks/pick-and-release.toml"),
    ),
    (
        "tasks/auto-pick-and-release.toml",
        include_str!("../configs/tasks/auto-pick-and-release.toml"),
    ),
    (
        "scenes/egg.toml",
        include_str!("../configs/scenes/egg.toml"),
    ),
    (
        "scenes/paper-cup.toml",
        include_str!("../configs/scenes/paper-cup.toml"),
    ),
    (
        "scenes/rubber-duck.toml",
        include_str!("../configs/scenes/rubber-duck.toml"),
    ),
    (
        "scenes/screwdriver.toml",
        include_str!("../configs/scenes/screwdriver.toml"),
    ),
    (
        "scenes/tennis-ball.toml",
        include_str!("../configs/scenes/tennis-ball.toml"),
    ),
    (
        "scenes/toy-corn.toml",
        include_str!("../configs/scenes/toy-corn.toml"),
    ),
]);

/// Names of the embedded task scripts (`tasks/NAME.toml`).
pub const TASKS: &[&str] = &["auto-pick-and-release", "pick-and-release", "screwdriver"];

/// Names of the embedded scenes (`scenes/NAME.toml`).
pub const SCENES: &[&str] = &[
    "egg",
    "paper-cup",
    "rubber-duck",
    "screwdriver",
    "tennis-ball",
    "toy-corn",
];
