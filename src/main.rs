//! `gelgrip`: the command-line entry point. Parses arguments, sets up logging and hands off to
//! a command; the wiring of concrete adapters lives in the `gelgrip` library.

mod cli;
mod commands;

use gelgrip_controller::config::ConfigError;

use std::process::ExitCode;

use clap::Parser;

use cli::{BenchCommand, Cli, Command, EmulateCommand};

fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .init();
}

/// Exit code 2 for usage and configuration errors, 1 for runtime faults (CONTRACTS.md),
/// from the error's type: the library's [`gelgrip::Error`] knows its own; a command's
/// usage error and a configuration error it met directly are 2.
fn exit_code_for(err: &anyhow::Error) -> u8 {
    if let Some(e) = err.downcast_ref::<gelgrip::Error>() {
        return e.exit_code();
    }
    let usage = err.downcast_ref::<gelgrip::UsageError>().is_some()
        || err.downcast_ref::<ConfigError>().is_some();
    if usage { 2 } else { 1 }
}

/// A bench, with this program's composition root as its rig.
async fn run_bench(command: BenchCommand) -> anyhow::Result<u8> {
    use gelgrip_bench as bench;
    let rig = &gelgrip::rig::ProgramRig;
    match command {
        BenchCommand::Bus(args) => bench::bus::run(rig, args).await,
        BenchCommand::Pipeline(args) => bench::pipeline::run(rig, args),
        BenchCommand::Grasp(args) => bench::grasp::run(rig, args).await,
        BenchCommand::Sync(args) => bench::sync::run(rig, args).await,
        BenchCommand::Calibration(args) => bench::calibration::run(rig, args),
        BenchCommand::Tradeoff(args) => bench::tradeoff::run(rig, args),
        BenchCommand::Soak(args) => bench::soak::run(rig, args).await,
        BenchCommand::Label(args) => bench::label::run(rig, args),
        BenchCommand::Dashboard(args) => bench::dashboard::run(args).await,
        BenchCommand::Slip(args) => bench::slip::run(rig, args),
    }
}

/// Cap glibc's malloc arenas at one per CPU (at least 2), unless the user set
/// `MALLOC_ARENA_MAX` or `GLIBC_TUNABLES` themselves. By default glibc gives each thread that
/// allocates while another holds an arena a new one, up to 8 per CPU, and each arena keeps
/// the high-water mark of what its threads held: over a long run the pipeline's, the
/// runtime's and the HTTP server's threads spread over ever more arenas and the resident
/// memory climbs in steps long after the run's own buffers are full (the virtual soak's
/// last quarter 2.3–4.5% over its first; with the cap 0.1–1.3%, docs/architecture.md,
/// "Memory over a long run"). Called first thing, before any other thread exists.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
fn cap_malloc_arenas() {
    if std::env::var_os("MALLOC_ARENA_MAX").is_some()
        || std::env::var_os("GLIBC_TUNABLES").is_some()
    {
        return;
    }
    let cpus = std::thread::available_parallelism().map_or(2, std::num::NonZeroUsize::get);
    let arenas = libc::c_int::try_from(cpus.max(2)).unwrap_or(libc::c_int::MAX);
    // SAFETY: `mallopt` only sets a tunable of the allocator, takes no pointers, and is
    // called before this process starts any thread; a value it refuses leaves glibc's
    // default in place (its return value, 0, says so and is not needed).
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, arenas);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn cap_malloc_arenas() {}

fn main() -> ExitCode {
    cap_malloc_arenas();
    let cli = Cli::parse();
    init_logging();
    // One pool worker per CPU, each on its own: the last frame's halves start at once.
    match gelgrip_plugins::halves::pin_global_pool() {
        Ok(cpus) => tracing::debug!(?cpus, "pool workers pinned"),
        Err(e) => tracing::warn!(error = %e, "pool workers not pinned"),
    }
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("error: cannot start the async runtime: {e}");
            return ExitCode::from(1);
        }
    };
    let result = runtime.block_on(async {
        match cli.command.unwrap_or(Command::Run(cli.run)) {
            Command::Run(args) => commands::run::run(args).await,
            Command::CheckConfig(args) => commands::check_config::run(args),
            Command::Bench(bench) => run_bench(bench).await,
            Command::Calibrate(cmd) => commands::calibrate::run(cmd).await,
            Command::Depth(args) => commands::depth::run(args),
            Command::Reconstruct(args) => commands::reconstruct::run(args),
            Command::Emulate(EmulateCommand::Servos(args)) => commands::emulate::run(args).await,
            Command::Emulate(EmulateCommand::Hub(args)) => commands::emulate_hub::run(args).await,
            Command::Servo(args) => commands::servo::run(args),
            Command::Plot(args) => gelgrip_bench::task_log_plot::run(args),
            Command::Replay(args) => commands::replay::run(args).await,
            Command::Record(cli::RecordCommand::Info(args)) => commands::record_info::run(args),
            Command::Record(cli::RecordCommand::Export(args)) => {
                commands::record_export::run(args).await
            }
        }
    });
    match result {
        Ok(code) => ExitCode::from(code),
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::from(exit_code_for(&err))
        }
    }
}
