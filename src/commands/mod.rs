//! One module per subcommand.

pub mod bench_bus;
pub mod bench_calibration;
pub mod bench_dashboard;
pub mod bench_grasp;
pub mod bench_pipeline;
pub mod bench_soak;
pub mod bench_sync;
pub mod bench_tradeoff;
pub mod calibrate;
pub mod calibrate_collect_hw;
pub mod calibrate_collect_view;
pub mod calibrate_force;
pub mod calibrate_force_hw;
pub mod calibrate_label;
pub mod check_config;
pub mod dashboard_child;
pub mod depth;
pub mod emulate;
pub mod emulate_hub;
pub mod plot;
pub mod record_export;
pub mod record_export_mcap;
pub mod record_info;
pub mod replay;
pub mod run;
pub mod servo;
