//! Two simulated grippers in one process, each with its own hub, servos, simulated world
//! and name in the logs, on their own virtual clocks: the left one grasps the tennis ball,
//! the right one the rubber duck, at the same time. `cargo run --release --example
//! two_grippers`
use gelgrip::session::{RunOptions, Session};
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::grasp::{GraspOutcome, GraspRequest};
use gelgrip_controller::runtime::outcome::EndReason;
use tracing::Instrument;

/// Open a simulated gripper on `scene`, grasp its object at 1.5 N per finger, and let go.
async fn grasp(scene: &str) -> anyhow::Result<GraspOutcome> {
    let options = RunOptions {
        scene: Some(scene.into()),
        clock: ClockKind::Virtual,
        headless: true,
        grasp_api: true,
        ..RunOptions::default()
    };
    let mut session = Session::open(&options).await?;
    let gripper = session
        .runtime
        .gripper()
        .expect("the simulated hand has fingers");
    let request = GraspRequest {
        target_force_n: 1.5,
        speed_deg_s: 15.0,
        current_limit_ma: session.config().servos.current_limit_ma,
        fingers: vec![0, 1, 2],
        timeout_s: 20.0,
        auto_target: false,
    };
    let (_events, stop) = tokio::sync::mpsc::channel(1);
    let result = tokio::select! {
        outcome = gripper.grasp(request) => outcome?,
        end = session.runtime.run(stop) => anyhow::bail!("the run ended first: {end}"),
    };
    tracing::info!(
        grasped = result.grasped,
        reason = %result.reason,
        "grasp done"
    );
    session.finish(EndReason::Done);
    Ok(result)
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    let left = grasp("configs/scenes/tennis-ball.toml")
        .instrument(tracing::info_span!("gripper", name = "left"));
    let right = grasp("configs/scenes/rubber-duck.toml")
        .instrument(tracing::info_span!("gripper", name = "right"));
    let (left, right) = tokio::join!(left, right);
    println!("left (tennis ball): {:?}", left?);
    println!("right (rubber duck): {:?}", right?);
    Ok(())
}
