//! One module per subcommand.

pub mod calibrate;
pub mod calibrate_collect_hw;
pub mod calibrate_collect_view;
pub mod calibrate_eval;
pub mod calibrate_force;
pub mod calibrate_force_hw;
pub mod calibrate_label;
pub mod check_config;
pub mod depth;
pub mod emulate;
pub mod emulate_hub;
pub mod mcap_out;
pub mod reconstruct;
pub mod record_export;
pub mod record_export_mcap;
pub mod record_info;
pub mod replay;
pub mod run;
pub mod servo;
