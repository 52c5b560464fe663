//! One module per subcommand.

pub mod bench_bus;
pub mod check_config;
pub mod run;
