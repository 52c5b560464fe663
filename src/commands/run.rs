//! `gelgrip run`: acquire and gate synchronized frame sets until the duration ends, a signal
//! arrives or the hub fails; log statistics once a second to stderr; print a report.

use std::sync::Arc;

use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::clock::{Clock, ClockKind};

use gelgrip_controller::hub::HubError;

use crate::cli::{ClockArg, RunArgs};
use crate::dashboard::Dashboard;
use crate::grasp_task::{GraspOptions, GraspTask};
use crate::gripper_loop::GripperLoop;
use crate::loop_control::LoopControl;
use crate::output::{RunReport, ServoReport, latency_ms};
use crate::recording::RunRecorder;
use crate::scene_report::SceneReport;
use crate::script_task::load_script;
use crate::servo_loop::ServoLoop;
use crate::tactile::Tactile;
use crate::tasks::Task;

use crate::wiring;

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

/// Resolves at `deadline_us` on a real clock; never on a virtual one (whose time only moves
/// with the work, so the loop checks it after each set instead).
async fn real_deadline(clock: Arc<dyn Clock>, deadline_us: Option<u64>) {
    match deadline_us {
        Some(d) if clock.kind() == ClockKind::Real => clock.sleep_until(d).await,
        _ => std::future::pending().await,
    }
}

/// The dashboard's next request to the run loop; never without a dashboard.
async fn next_request(control: Option<&mut LoopControl>) -> gelgrip_web::control::LoopCommand {
    match control {
        Some(c) => c.recv().await,
        None => std::future::pending().await,
    }
}

struct Progress {
    last_log_us: u64,
    last_sets: u64,
    /// The "every set is too old" hint was given.
    hinted_late: bool,
}

/// Rejected-late sets, with none emitted, before the run says why.
const LATE_HINT_SETS: u64 = 20;

impl Progress {
    fn log(&mut self, acq: &Acquisition, now_us: u64) {
        if now_us < self.last_log_us + 1_000_000 {
            return;
        }
        let stats = acq.gate().stats();
        let window_s = (now_us - self.last_log_us) as f64 / 1e6;
        let rate = (stats.sets - self.last_sets) as f64 / window_s;
        tracing::info!(
            sets = stats.sets,
            rate_hz = format!("{rate:.1}"),
            spread_us_p99 = stats.spread_us_p99().unwrap_or(0),
            frames_dropped = stats.drops.total(),
            sets_rejected = stats.sets_rejected.total(),
            "acquisition"
        );
        self.last_log_us = now_us;
        self.last_sets = stats.sets;
        if !self.hinted_late && stats.sets == 0 && stats.sets_rejected.late >= LATE_HINT_SETS {
            self.hinted_late = true;
            tracing::warn!(
                rejected_late = stats.sets_rejected.late,
                max_age_ms = acq.gate().limits().max_age_us as f64 / 1e3,
                "every set so far arrived older than the gate's max age: the bus model \
                 underestimates the latency. Check the hub's section (a full-speed CDC hub \
                 needs [hub.cdc] usb = \"fs\") or set [gate] max_age_ms"
            );
        }
    }
}

/// Longest wait for the untouched sets of a hardware hub's references.
const REFERENCE_TIMEOUT_S: u64 = 10;

/// On a hardware hub, take the sensors' references on the first gated sets, before the
/// loop (nothing touches the sensors: the gripper starts open). Nothing to do on the
/// simulator.
async fn reference_live(
    acq: &mut Acquisition,
    tactile: &mut Tactile,
    clock: &dyn Clock,
    transport: &str,
) -> anyhow::Result<()> {
    let missing = tactile.reference_sets_missing();
    if missing == 0 {
        return Ok(());
    }
    tracing::info!(sets = missing, "referencing the sensors on untouched sets");
    let give_up = clock.now_us() + REFERENCE_TIMEOUT_S * 1_000_000;
    while tactile.reference_sets_missing() > 0 {
        let Some(set) = acq.next_set_before(give_up).await? else {
            anyhow::bail!(
                "no synchronized set from the {transport} hub in {REFERENCE_TIMEOUT_S} s: the \
                 sensors' references could not be taken (gate: {:?})",
                acq.gate().stats()
            );
        };
        tactile.offer_reference(&set);
    }
    Ok(())
}

/// Run the command; returns the exit code.
pub async fn run(args: RunArgs) -> anyhow::Result<u8> {
    let registry = wiring::registry();
    let (config, config_files) = wiring::load_config_with_files(args.config.as_deref(), &registry)?;
    let clock_arg = args.clock.unwrap_or(ClockArg::Real);
    let clock = wiring::make_clock(clock_arg);
    let world = wiring::open_world(&config, args.scene.as_deref())?;
    let registry = match &world {
        Some(w) => wiring::registry_with_world(w.clone()),
        None => registry,
    };
    let on_scene = world
        .as_ref()
        .and_then(|w| w.lock().ok().map(|w| w.scene().is_some()))
        .unwrap_or(false);
    let mut acq = wiring::open_acquisition(&config, &registry, clock.clone()).await?;
    let description = acq.hub().describe().clone();
    let recorder = match &args.record {
        Some(dir) => {
            let r = RunRecorder::start(
                dir,
                &config,
                config_files,
                &description,
                acq.gate().limits(),
            )?;
            acq = acq.with_tap(r.tap());
            Some(r)
        }
        None => None,
    };
    tracing::info!(
        transport = description.transport,
        sensors = description.sensors,
        trigger = description.trigger.as_str(),
        max_spread_us = acq.gate().limits().max_spread_us,
        max_age_us = acq.gate().limits().max_age_us,
        "acquiring"
    );
    let start = clock.now_us();
    let mut progress = Progress {
        last_log_us: start,
        last_sets: 0,
        hinted_late: false,
    };
    let mut faults = Vec::new();
    let bus = wiring::open_servos(&config, world.as_ref(), clock.clone())?;
    let mut task = None;
    let mut servos = None;
    // The dashboard's grasp needs every sensor's pipeline; on a hardware hub without model
    // files the dashboard still serves the cameras, sync and servos.
    let unmodelled = crate::tactile::sensors_without_model(&config)?;
    let dashboard_grasp = !args.headless && unmodelled.is_empty();
    if !args.headless && args.task.is_none() && !unmodelled.is_empty() {
        tracing::warn!(
            sensors = unmodelled.join(", "),
            "no gradient model file for these sensors on the {} hub: the dashboard serves \
             the cameras, sync and servos, without the grasp (docs/pipeline.md)",
            config.hub.transport
        );
    }
    match (args.task.as_deref(), bus) {
        (Some("gentle-grasp"), Some(bus)) => {
            let options = GraspOptions {
                target_force_n: args.target_force,
                speed_deg_s: args.speed,
                timeout_s: args.task_timeout,
                hold_s: args.hold,
            };
            task = Some(Task::Grasp(Box::new(GraspTask::start(
                &config,
                bus,
                world.clone(),
                &options,
                args.log.as_deref(),
            )?)));
            tracing::info!(task = "gentle-grasp", "task running");
        }
        (Some(name), Some(bus)) => {
            let script = load_script(name, &config)?;
            tracing::info!(
                task = script.name,
                stages = script.stages.len(),
                "task script"
            );
            let mut gripper = GripperLoop::start(&config, bus, world.clone(), args.log.as_deref())?;
            gripper
                .start_script(script)
                .map_err(|running| anyhow::anyhow!("task {running} already running"))?;
            task = Some(Task::Gripper {
                gripper: Box::new(gripper),
                script_ends_run: true,
            });
        }
        (Some(name), None) => {
            if name != "gentle-grasp" {
                load_script(name, &config)?;
            }
            anyhow::bail!(crate::cli::UsageError(format!(
                "task {name} needs finger servos; layout {} has no [[fingers]]",
                config.layout.name
            )));
        }
        (None, Some(bus)) if dashboard_grasp => {
            task = Some(Task::Gripper {
                gripper: Box::new(GripperLoop::start(
                    &config,
                    bus,
                    world.clone(),
                    args.log.as_deref(),
                )?),
                script_ends_run: false,
            });
        }
        (None, Some(bus)) => {
            servos = Some(
                ServoLoop::start(bus, &config.layout, on_scene, args.close_current_ma, start)
                    .map_err(|e| anyhow::anyhow!("configuring the servos: {e}"))?,
            );
        }
        (None, None) => {}
    }
    if recorder.is_some()
        && let Some(t) = task.as_mut()
    {
        t.log_controller();
    }
    let mut control = None;
    let mut dashboard = if args.headless {
        None
    } else {
        let gripper = task.as_ref().map(Task::handle);
        let (c, requests) = LoopControl::new(&config, world.clone(), clock.clone());
        let bind = args.http.unwrap_or(config.http.bind);
        let mut d = Dashboard::start(
            &config,
            bind,
            gripper,
            Some(requests),
            description.transport.clone(),
        )
        .await?;
        d.sim = c.sim_view();
        control = Some(c);
        Some(d)
    };
    if let Some(t) = task.as_mut() {
        reference_live(
            &mut acq,
            t.tactile_mut(),
            clock.as_ref(),
            &description.transport,
        )
        .await?;
    }
    // `--duration` counts from here, after the set-up (on a fresh machine the sensors'
    // self-calibration takes seconds), so a short run still acquires for its duration.
    let run_start = clock.now_us();
    let deadline = args.duration.map(|s| run_start + (s * 1e6) as u64);
    let shutdown = shutdown_signal();
    let estop = estop_signal();
    let timer = real_deadline(clock.clone(), deadline);
    tokio::pin!(shutdown, estop, timer);
    // Wakes the loop when the hub is silent, so the watchdog and the dashboard still run.
    let mut tick = tokio::time::interval(std::time::Duration::from_millis(100));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let end_reason = loop {
        tokio::select! {
            biased;
            _ = &mut estop => {
                tracing::error!("e-stop: fingers hold at minimum current");
                faults.push("e-stop requested (SIGUSR1)".to_string());
                break "estop";
            }
            _ = &mut shutdown => break "signal",
            _ = &mut timer => break "duration",
            _ = tick.tick() => {}
            request = next_request(control.as_mut()) => {
                if let Some(c) = control.as_mut() {
                    c.handle(request, task.as_mut());
                    if let Some(d) = dashboard.as_mut() {
                        d.sim = c.sim_view();
                    }
                }
            }
            step = acq.step() => {
                match step {
                    Err(HubError::Finished { detail }) => {
                        tracing::info!("{detail}");
                        break "done";
                    }
                    Err(e) => {
                        tracing::error!("hub fault: {e}");
                        faults.push(e.to_string());
                        break "fault";
                    }
                    Ok(Some(set)) => {
                        if let Some(t) = task.as_mut() {
                            let outcome = t.on_set(&set, clock.now_us());
                            if let Some(r) = &recorder {
                                let events = t.take_controller_events();
                                r.snapshot(clock.now_us(), set.trigger_seq, Some(t), events);
                            }
                            match outcome {
                                Ok(Some(reason)) => break reason,
                                Ok(None) => {}
                                Err(e) => {
                                    tracing::error!("{e}");
                                    faults.push(e.to_string());
                                    break "fault";
                                }
                            }
                        }
                        if let Some(d) = dashboard.as_mut() {
                            let now = clock.now_us();
                            let t_s = (now - start) as f64 / 1e6;
                            d.publish(&set, task.as_ref(), acq.gate().stats(), t_s, now);
                        }
                    }
                    Ok(None) => {}
                }
            }
        }
        let now = clock.now_us();
        if let Some(reason) = task.as_mut().and_then(Task::apply_urgent) {
            break reason;
        }
        if let Some((fault, ends_run)) = task.as_mut().and_then(|t| t.watchdog(now)) {
            tracing::error!("{fault}");
            faults.push(fault);
            if ends_run {
                break "fault";
            }
        }
        if let Some(s) = servos.as_mut()
            && let Err(e) = s.tick(now)
        {
            tracing::error!("servo fault: {e}");
            faults.push(format!("servo fault: {e}"));
            break "fault";
        }
        if let Some(d) = dashboard.as_mut() {
            let t_s = (now - start) as f64 / 1e6;
            d.publish_if_quiet(task.as_ref(), acq.gate().stats(), t_s, now);
        }
        if deadline.is_some_and(|d| now >= d) {
            break "duration";
        }
        progress.log(&acq, now);
    };
    if let Some(s) = servos.as_mut() {
        faults.splice(0..0, s.recovered.drain(..));
        if end_reason == "estop" {
            s.estop();
        } else if let Err(e) = s.stop() {
            tracing::warn!("could not turn servo torque off: {e}");
        }
    }
    if let Some(t) = task.as_mut() {
        faults.splice(0..0, t.take_recovered());
        if end_reason == "estop" {
            t.estop();
        } else {
            t.finish();
        }
    }
    let scene = world.as_ref().and_then(|w| {
        let w = w.lock().ok()?;
        SceneReport::of(&w, &config.layout)
    });
    drop(acq.take_tap());
    let recording = recorder.map(|r| r.finish(clock.now_us()));
    if let Some(r) = &recording {
        if r.dropped_backpressure + r.dropped_io > 0 {
            tracing::warn!(
                backpressure = r.dropped_backpressure,
                io = r.dropped_io,
                "the recorder dropped records"
            );
        }
        if let Some(e) = &r.error {
            faults.push(format!("recording: {e}"));
        }
    }
    let stats = acq.gate().stats();
    let report = RunReport {
        recording,
        sensors: description.sensors,
        sets: stats.sets,
        set_rate_hz: stats.set_rate_hz(),
        spread_us_p99: stats.spread_us_p99(),
        faults,
        drops: stats.drops,
        sets_rejected: stats.sets_rejected,
        end_reason,
        transport: description.transport.clone(),
        trigger: description.trigger.as_str(),
        clock: match clock_arg {
            ClockArg::Real => "real",
            ClockArg::Virtual => "virtual",
        },
        elapsed_s: (clock.now_us() - run_start) as f64 / 1e6,
        max_spread_us: acq.gate().limits().max_spread_us,
        max_age_us: acq.gate().limits().max_age_us,
        set_latency_ms_p50: latency_ms(stats, 0.5),
        set_latency_ms_p99: latency_ms(stats, 0.99),
        frames_received: stats.frames_in,
        spread_histogram_us: stats.spread_buckets(),
        object: scene.as_ref().map(|s| s.object.clone()),
        crushed: scene.as_ref().map(|s| s.crushed),
        scene,
        servos: servos
            .as_ref()
            .map(|s| s.last.as_slice())
            .or(task.as_ref().map(|t| t.states()))
            .map(|s| s.iter().map(ServoReport::from).collect()),
        dashboard_url: dashboard.as_ref().map(|d| format!("http://{}/", d.addr)),
        task: task.as_ref().and_then(Task::report),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{}", report.to_text());
    }
    Ok(if matches!(end_reason, "fault" | "estop") {
        1
    } else {
        0
    })
}
