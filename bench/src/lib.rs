//! The paper's experiments and gelgrip's benchmarks, as the `gelgrip bench …` and
//! `gelgrip plot` commands run them: each module is one command, with its arguments
//! (clap), its runs and its output (a table, `--json`, plots). The binary calls them and
//! hands in its composition root as a [`rig::Rig`], through which the benches load
//! configs, open hubs and run the gripper; the rest they build from the adapters
//! directly (simulated cameras, pipelines, emulators).
//!
//! - the benches: [`bus`], [`pipeline`] (and [`pipeline_markers`], its slip detection), [`grasp`], [`sync`], [`dashboard`], [`soak`]
//!   (and [`soak_storm`], its virtual-clock storm), [`calibration`], [`label`] (and
//!   [`label_sphere`], its sphere check), [`tradeoff`], [`slip`]; and [`task_log_plot`] (`gelgrip
//!   plot`);
//! - their parts: [`plot`] (figures as SVG or PNG), [`config_files`] (configs derived from
//!   a base file), [`sensor_models`] (a simulated hand's calibrated models),
//!   [`dashboard_child`] (a `gelgrip run` child serving its dashboard), [`progress`];
//! - [`args`]: the command-line vocabulary the benches share with the binary's commands.
//!
//! Like the binary's commands, the benches report failures through `anyhow`: each is a
//! command's whole run, and what it does with an error is print it.

pub mod args;
pub mod bus;
pub mod calibration;
pub mod config_files;
pub mod dashboard;
pub mod dashboard_child;
pub mod grasp;
pub mod label;
pub mod label_sphere;
pub mod pipeline;
pub mod pipeline_markers;
pub mod plot;
pub mod progress;
pub mod rig;
pub mod sensor_models;
pub mod slip;
pub mod soak;
pub mod soak_storm;
pub mod sync;
pub mod task_log_plot;
pub mod tradeoff;
