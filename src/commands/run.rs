//! `gelgrip run`: the gripper's run loop (the library's [`Session`]) until the duration
//! ends, a signal arrives, the task ends or a fault stops it; statistics once a second to
//! stderr; a report at the end.

use crate::cli::{ClockArg, parse_current_ma, parse_duration, parse_lift_rise_s, parse_within};
use clap::Args;
use gelgrip::session::{RunOptions, Session};
use gelgrip_controller::actuator::XM430_W350;
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::grasp::{MAX_TIMEOUT_S, TargetForce};
use gelgrip_controller::runtime::RuntimeEvent;
use gelgrip_controller::runtime::gentle_grasp::{GraspOptions, LIFT_RISE_S};
use gelgrip_ros_bridge::publisher::RosPublisher;
use std::path::PathBuf;
use tokio::sync::mpsc;

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

/// The scene the dashboard run of the default config opens on.
pub const DASHBOARD_SCENE: &str = "tennis-ball";

impl From<&RunArgs> for RunOptions {
    fn from(args: &RunArgs) -> Self {
        Self {
            config: args.config.clone(),
            scene: args.scene.clone(),
            // The README's first command shows the product working: the default config's
            // dashboard run opens on an object (every other run keeps the config's scene).
            default_scene: (args.config.is_none() && !args.headless)
                .then(|| DASHBOARD_SCENE.to_string()),
            clock: args.clock.map_or(ClockKind::Real, ClockKind::from),
            task: args.task.clone(),
            grasp: GraspOptions {
                target_force: args.target_force,
                speed_deg_s: args.speed,
                timeout_s: args.task_timeout,
                hold_s: args.hold,
                lift_rise_s: args.lift_rise_s,
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
    let mut options = RunOptions::from(&args);
    // Publishing to ROS 2 drives through the grasp API (readings and servos to publish).
    options.grasp_api |= args.ros || args.ros_namespace.is_some();
    let mut session = Session::open(&options).await?;
    let ros = RosPublisher::for_run(session.config(), args.ros, args.ros_namespace.as_deref())
        .map_err(gelgrip::Error::from)?;
    if let Some(publisher) = ros {
        let commands = gelgrip_ros_bridge::command::RosCommands::for_run(
            session.config(),
            &publisher,
            session.runtime.gripper(),
        )
        .map_err(gelgrip::Error::from)?;
        // The command side first: it sees each pass right after the servo write.
        if let Some(c) = commands {
            session.runtime.observe(Box::new(c));
        }
        session.runtime.observe(Box::new(publisher));
    }
    let report = session.run(signal_events()).await;
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", report.to_text());
    }
    Ok(report.end_reason.exit_code())
}

/// `gelgrip run`.
#[derive(Debug, Clone, Args, Default)]
pub struct RunArgs {
    /// Configuration file (default: the embedded simulated gripper).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Stop after this many seconds (of the chosen clock).
    #[arg(long, value_parser = parse_duration)]
    pub duration: Option<f64>,
    /// No HTTP server and no dashboard.
    #[arg(long)]
    pub headless: bool,
    /// Serve the dashboard on this address instead of `[http] bind` (port 0: any free
    /// port; the URL is printed to stderr).
    #[arg(long, value_name = "ADDR", conflicts_with = "headless")]
    pub http: Option<std::net::SocketAddr>,
    /// Time source (default real).
    #[arg(long, value_enum)]
    pub clock: Option<ClockArg>,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
    /// Close the fingers on this scene file (overrides `[hub.sim] scene`; sim hub only).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Goal-current cap the fingers ramp to when closing on a scene without a task, mA.
    #[arg(long, default_value_t = 800.0, value_parser = parse_current_ma)]
    pub close_current_ma: f64,
    /// Run a task: `gentle-grasp` (built in), a task script NAME (`configs/tasks/NAME.toml`,
    /// or the embedded copy: `screwdriver`), or a script FILE (anything with a `/` or
    /// ending in `.toml`). See docs/tasks.md.
    #[arg(long)]
    pub task: Option<String>,
    /// Gentle grasp: force per finger, N: above 0 and at most what the configured fingers
    /// can press with at the current limit (163.7 N on the shipped hand at 1000 mA; checked
    /// once the config is loaded, docs/control.md); or `auto`: the grasp closes to
    /// `[grasp] preload_n` and its slip reflex finds the force.
    #[arg(long, default_value = "1.5")]
    pub target_force: TargetForce,
    /// Gentle grasp: approach speed, deg/s of servo rotation, in (0, 276]: the XM430-W350's
    /// no-load speed (faster approaches touch harder: see docs/control.md).
    #[arg(long, default_value_t = 15.0, value_parser = parse_speed_deg_s)]
    pub speed: f64,
    /// Gentle grasp: give up after this many seconds, in (0, 120].
    #[arg(long, default_value_t = 20.0, value_parser = parse_task_timeout_s)]
    pub task_timeout: f64,
    /// Gentle grasp: once stable, keep holding (and regulating) for this many seconds
    /// before the hold test and the end of the task.
    #[arg(long, default_value_t = 0.0, value_parser = parse_hold_s)]
    pub hold: f64,
    /// Gentle grasp under `--target-force auto`, on the simulator: after the grasp settles
    /// the object is let go and its weight comes on over this many seconds (how fast the
    /// robot loads the grasp), in [0, 60].
    #[arg(long, default_value_t = LIFT_RISE_S, value_parser = parse_lift_rise_s)]
    pub lift_rise_s: f64,
    /// Write the task's signals (time, stage, deformation per sensor, state and force per
    /// finger) to this CSV file.
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Record everything the run sees (hub events, gate decisions, servo, controller and
    /// task states, the config) into this directory (docs/recording.md).
    #[arg(long, value_name = "DIR")]
    pub record: Option<PathBuf>,
    /// Publish to ROS 2 over Zenoh (the `[ros]` section, enabled; docs/ros.md).
    #[arg(long)]
    pub ros: bool,
    /// The ROS namespace of this gripper's node and topics (overrides `ros.namespace`;
    /// implies `--ros`).
    #[arg(long, value_name = "NS", value_parser = parse_ros_namespace)]
    pub ros_namespace: Option<String>,
}

/// `s` as a number in (0, `max`] `unit`, or a message naming the range and `why`.
fn parse_up_to(s: &str, what: &str, unit: &str, max: f64, why: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not {what} in {unit}"))?;
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(format!("{s} {unit} is outside (0, {max}] {unit}: {why}"))
    }
}

fn parse_speed_deg_s(s: &str) -> Result<f64, String> {
    let why = XM430_W350.no_load_speed_text();
    parse_up_to(s, "a speed", "deg/s", XM430_W350.no_load_deg_s(), &why)
}

fn parse_task_timeout_s(s: &str) -> Result<f64, String> {
    parse_up_to(
        s,
        "a duration",
        "s",
        MAX_TIMEOUT_S,
        "the longest a grasp may take",
    )
}

fn parse_ros_namespace(s: &str) -> Result<String, String> {
    gelgrip_ros_wire::names::check_namespace(s).map_err(|e| e.to_string())?;
    Ok(s.to_string())
}

fn parse_hold_s(s: &str) -> Result<f64, String> {
    parse_within(s, "a duration", "s", 0.0..=3600.0)
}
