//! `gelgrip run`: the gripper's run loop (the library's [`Session`]) until the duration
//! ends, a signal arrives, the task ends or a fault stops it; statistics once a second to
//! stderr; a report at the end.

use gelgrip::session::{RunOptions, Session};
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::runtime::RuntimeEvent;
use gelgrip_controller::runtime::gentle_grasp::GraspOptions;
use tokio::sync::mpsc;

use crate::cli::RunArgs;

/// Resolves on SIGINT or SIGTERM.
pub async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}

/// Resolves when an e-stop is requested: SIGUSR1 (from a supervisor or a hardware e-stop
/// watcher; the dashboard adds its own button). Never on systems without it.
async fn estop_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        if let Ok(mut usr1) = signal(SignalKind::user_defined1()) {
            usr1.recv().await;
            return;
        }
    }
    std::future::pending::<()>().await;
}

/// The process's signals as the runtime's events: SIGUSR1 is an e-stop, SIGINT and
/// SIGTERM a shutdown. The signal handlers are installed before this returns.
fn signal_events() -> mpsc::Receiver<RuntimeEvent> {
    let (tx, rx) = mpsc::channel(2);
    let shutdown = shutdown_signal();
    let estop = estop_signal();
    tokio::spawn(async move {
        tokio::pin!(shutdown, estop);
        let event = tokio::select! {
            biased;
            _ = &mut estop => RuntimeEvent::Estop,
            _ = &mut shutdown => RuntimeEvent::Shutdown,
        };
        let _ = tx.send(event).await;
    });
    rx
}

impl From<&RunArgs> for RunOptions {
    fn from(args: &RunArgs) -> Self {
        Self {
            config: args.config.clone(),
            scene: args.scene.clone(),
            clock: args.clock.map_or(ClockKind::Real, ClockKind::from),
            task: args.task.clone(),
            grasp: GraspOptions {
                target_force_n: args.target_force,
                speed_deg_s: args.speed,
                timeout_s: args.task_timeout,
                hold_s: args.hold,
            },
            log: args.log.clone(),
            record: args.record.clone(),
            headless: args.headless,
            grasp_api: false,
            http: args.http,
            close_current_ma: args.close_current_ma,
            duration_s: args.duration,
        }
    }
}

/// Run the command; returns the exit code.
pub async fn run(args: RunArgs) -> anyhow::Result<u8> {
    let session = Session::open(&RunOptions::from(&args)).await?;
    let report = session.run(signal_events()).await;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", report.to_text());
    }
    Ok(report.end_reason.exit_code())
}
