//! A gentle grasp of the simulated tennis ball through the gelgrip library: the simulated
//! gripper on the virtual clock, the grasp API asked for 1.5 N per finger while the
//! runtime runs, and the result printed. `cargo run --release --example gentle_grasp`
use gelgrip::session::{RunOptions, Session};
use gelgrip_controller::runtime::outcome::EndReason;
use gelgrip_controller::{clock::ClockKind, grasp::GraspRequest};

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    let options = RunOptions {
        scene: Some("configs/scenes/tennis-ball.toml".into()),
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
    println!("{result:?}");
    session.finish(EndReason::Done);
    Ok(())
}
