//! The gripper from Python, on the same `Runtime` the CLI runs (the library's `Session`):
//! it runs on a thread of its own with its own tokio runtime, headless, driven through the
//! grasp API. Each gated set's report goes into a bounded queue (the oldest is dropped when
//! a slow reader lets it fill, and the next report read says how many were); grasps,
//! release, stop and e-stop go through the runtime's `GripperHandle`. Blocking calls wait
//! with the GIL released, in short slices between which Ctrl-C is checked: a
//! `KeyboardInterrupt` during a grasp stops the fingers. Closing (or leaving the `with`
//! block) ends the run as the CLI does on SIGINT, which brings the hardware to its safe
//! state, and returns the `run --json` report.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use pyo3::exceptions::{PyTimeoutError, PyValueError};
use pyo3::prelude::*;
use tokio::sync::mpsc;

use gelgrip::output::RunReport;
use gelgrip::session::{RunOptions, Session};
use gelgrip_controller::clock::ClockKind;
use gelgrip_controller::grasp::{GraspRequest, TargetForce};
use gelgrip_controller::gripper::{GripperError as RustGripperError, GripperHandle, PendingGrasp};
use gelgrip_controller::runtime::RuntimeEvent;
use gelgrip_controller::runtime::outcome::EndReason;

use crate::errors::{self, GripperError};

mod sets;

pub use sets::GripperSet;
use sets::{QueueObserver, SetQueue};

/// A blocking wait re-checks Ctrl-C this often.
const SLICE: Duration = Duration::from_millis(20);

/// What the run thread hands back once the session is open.
struct Opened {
    handle: GripperHandle,
    current_limit_ma: f64,
    fingers: usize,
}

/// A gripper that runs.
struct Running {
    handle: GripperHandle,
    events: mpsc::Sender<RuntimeEvent>,
    thread: JoinHandle<Option<RunReport>>,
    current_limit_ma: f64,
    fingers: usize,
}

/// Open the session on this (the run) thread, hand the handle back through `ready`, and
/// run until an event ends it.
fn run_thread(
    options: RunOptions,
    queue: Arc<SetQueue>,
    events: mpsc::Receiver<RuntimeEvent>,
    ready: std::sync::mpsc::Sender<Result<Opened, PyErr>>,
) -> Option<RunReport> {
    let runtime = match tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("gelgrip-runtime")
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            let _ = ready.send(Err(errors::DeviceError::new_err(format!(
                "the gripper's async runtime: {e}"
            ))));
            queue.end();
            return None;
        }
    };
    let observer_queue = queue.clone();
    let report = runtime.block_on(async move {
        let mut session = match Session::open(&options).await {
            Ok(s) => s,
            Err(e) => {
                let _ = ready.send(Err(errors::gelgrip(&e)));
                return None;
            }
        };
        let Some(handle) = session.runtime.gripper() else {
            let _ = ready.send(Err(errors::ConfigError::new_err(
                "the config's layout has no fingers to drive: no gripper",
            )));
            let _ = session.finish(EndReason::Done);
            return None;
        };
        let ids = session
            .config()
            .layout
            .sensors
            .iter()
            .map(|s| s.id.to_string())
            .collect();
        session.runtime.observe(Box::new(QueueObserver {
            queue: observer_queue,
            ids,
        }));
        let opened = Opened {
            handle,
            current_limit_ma: session.config().servos.current_limit_ma,
            fingers: session.config().layout.fingers.len(),
        };
        if ready.send(Ok(opened)).is_err() {
            return Some(session.finish(EndReason::Signal));
        }
        Some(session.run(events).await)
    });
    queue.end();
    report
}

/// The gripper (`config` None: the embedded simulated gripper), run headless through the
/// grasp API.
#[pyclass(module = "gelgrip")]
pub struct Gripper {
    running: Mutex<Option<Running>>,
    queue: Arc<SetQueue>,
    /// The `run --json` report, once closed.
    report: Mutex<Option<String>>,
}

fn closed() -> PyErr {
    GripperError::new_err("the gripper is closed")
}

fn gripper_error(e: &RustGripperError) -> PyErr {
    match e {
        RustGripperError::InvalidRequest { .. } => PyValueError::new_err(e.to_string()),
        _ => GripperError::new_err(e.to_string()),
    }
}

/// Wait for `pending` in slices, checking Ctrl-C between them (a Ctrl-C stops the
/// fingers and raises); `None` on a timeout.
fn wait_outcome(
    py: Python<'_>,
    pending: &mut PendingGrasp,
    handle: &GripperHandle,
    timeout: Option<f64>,
) -> PyResult<Option<gelgrip_controller::grasp::GraspOutcome>> {
    let deadline = timeout.map(|t| Instant::now() + Duration::from_secs_f64(t.max(0.0)));
    loop {
        if let Some(outcome) = pending.try_outcome() {
            return outcome.map(Some).map_err(|e| gripper_error(&e));
        }
        if deadline.is_some_and(|d| Instant::now() >= d) {
            return Ok(None);
        }
        py.detach(|| std::thread::sleep(SLICE.min(Duration::from_millis(5))));
        if let Err(interrupt) = py.check_signals() {
            let _ = handle.stop();
            return Err(interrupt);
        }
    }
}

/// `target_force_n` as Python passes it: a number of N, or `"auto"`.
#[derive(FromPyObject)]
enum ForceArg {
    Newtons(f64),
    Text(String),
}

impl ForceArg {
    /// The force, or a `ValueError` naming the argument.
    fn target(self) -> PyResult<TargetForce> {
        match self {
            Self::Newtons(n) => Ok(TargetForce::Newtons(n)),
            Self::Text(s) if s == "auto" => Ok(TargetForce::Auto),
            Self::Text(s) => Err(PyValueError::new_err(format!(
                "target_force_n = {s:?}: expected a force in N or \"auto\""
            ))),
        }
    }
}

impl Gripper {
    fn with_running<T>(&self, f: impl FnOnce(&Running) -> PyResult<T>) -> PyResult<T> {
        let guard = self.running.lock().map_err(|_| closed())?;
        match guard.as_ref() {
            Some(r) => f(r),
            None => Err(closed()),
        }
    }

    fn request(
        &self,
        target_force_n: ForceArg,
        speed_deg_s: f64,
        timeout_s: f64,
        fingers: Option<Vec<usize>>,
        current_limit_ma: Option<f64>,
    ) -> PyResult<(GripperHandle, GraspRequest)> {
        let target = target_force_n.target()?;
        self.with_running(|r| {
            let (target_force_n, auto_target) = r.handle.target(target);
            Ok((
                r.handle.clone(),
                GraspRequest {
                    target_force_n,
                    speed_deg_s,
                    current_limit_ma: current_limit_ma.unwrap_or(r.current_limit_ma),
                    fingers: fingers.unwrap_or_else(|| (0..r.fingers).collect()),
                    timeout_s,
                    auto_target,
                },
            ))
        })
    }
}

/// Build the run options from the constructor's arguments.
fn options(config: Option<PathBuf>, clock: &str, scene: Option<String>) -> PyResult<RunOptions> {
    let clock = match clock {
        "real" => ClockKind::Real,
        "virtual" => ClockKind::Virtual,
        other => {
            return Err(PyValueError::new_err(format!(
                "clock={other:?}: expected \"real\" or \"virtual\""
            )));
        }
    };
    if let Some(path) = &config {
        errors::require_file(path, "config")?;
    }
    // A path overrides the config's scene, as `run --scene`; a name is an embedded scene.
    let (scene_path, scene_name) = match scene {
        Some(s) if s.contains('/') || s.ends_with(".toml") => {
            let p = PathBuf::from(s);
            errors::require_file(&p, "scene")?;
            (Some(p), None)
        }
        other => (None, other),
    };
    Ok(RunOptions {
        config,
        scene: scene_path,
        default_scene: scene_name,
        clock,
        headless: true,
        grasp_api: true,
        ..RunOptions::default()
    })
}

#[pymethods]
impl Gripper {
    /// Open the gripper: `config` a config file (None: the embedded simulated gripper),
    /// `clock` `"real"` or `"virtual"` (the host's pace, as `run --clock virtual`), `scene`
    /// a scene file (as `run --scene`) or the name of an embedded one (`tennis-ball`,
    /// `egg`, …, for a simulated config that names none); `queue` the most set reports
    /// kept for a slow reader.
    #[new]
    #[pyo3(signature = (config=None, clock="real", scene=None, queue=64))]
    fn new(
        py: Python<'_>,
        config: Option<PathBuf>,
        clock: &str,
        scene: Option<String>,
        queue: usize,
    ) -> PyResult<Self> {
        if queue == 0 {
            return Err(PyValueError::new_err("queue=0: expected at least 1"));
        }
        let options = options(config, clock, scene)?;
        let sets = Arc::new(SetQueue::new(queue));
        let (events_tx, events_rx) = mpsc::channel(4);
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let thread_sets = sets.clone();
        let thread = std::thread::Builder::new()
            .name("gelgrip-gripper".into())
            .spawn(move || run_thread(options, thread_sets, events_rx, ready_tx))
            .map_err(|e| GripperError::new_err(format!("starting the gripper's thread: {e}")))?;
        let opened = py.detach(move || ready_rx.recv());
        let opened = match opened {
            Ok(Ok(o)) => o,
            Ok(Err(e)) => {
                let _ = py.detach(|| thread.join());
                return Err(e);
            }
            Err(_) => {
                let _ = py.detach(|| thread.join());
                return Err(GripperError::new_err(
                    "the gripper's thread ended while opening",
                ));
            }
        };
        Ok(Self {
            running: Mutex::new(Some(Running {
                handle: opened.handle,
                events: events_tx,
                thread,
                current_limit_ma: opened.current_limit_ma,
                fingers: opened.fingers,
            })),
            queue: sets,
            report: Mutex::new(None),
        })
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (*_args))]
    fn __exit__(&self, py: Python<'_>, _args: &Bound<'_, pyo3::types::PyTuple>) -> PyResult<bool> {
        self.close(py)?;
        Ok(false)
    }

    /// End the run as the CLI does on SIGINT (the hardware to its safe state); the
    /// `run --json` report as a dict (the same one again on a second call).
    fn close<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let running = self.running.lock().map_err(|_| closed())?.take();
        if let Some(r) = running {
            let _ = r.events.try_send(RuntimeEvent::Shutdown);
            let report = py.detach(|| r.thread.join()).ok().flatten();
            if let Some(report) = report {
                let text = serde_json::to_string(&report)
                    .map_err(|e| errors::GelgripError::new_err(format!("report: {e}")))?;
                if let Ok(mut slot) = self.report.lock() {
                    *slot = Some(text);
                }
            }
        }
        let text = self.report.lock().ok().and_then(|r| r.clone());
        text.map(|t| py.import("json")?.call_method1("loads", (t,)))
            .transpose()
    }

    /// The next gated set's report, waiting at most `timeout` s of wall clock (None: until
    /// one comes); `TimeoutError` when none came, `GripperError` when the run has ended.
    #[pyo3(signature = (timeout=None))]
    fn next_set(&self, py: Python<'_>, timeout: Option<f64>) -> PyResult<GripperSet> {
        if timeout.is_some_and(|t| !t.is_finite() || t < 0.0) {
            return Err(PyValueError::new_err(
                "timeout: expected a finite number of seconds of at least 0, or None",
            ));
        }
        self.with_running(|_| Ok(()))?;
        let deadline = timeout.map(|t| Instant::now() + Duration::from_secs_f64(t));
        loop {
            let slice = deadline.map_or(SLICE, |d| {
                SLICE.min(d.saturating_duration_since(Instant::now()))
            });
            match py.detach(|| self.queue.pop(slice)) {
                Ok((set, dropped)) => return GripperSet::new(py, set, dropped),
                Err(true) => {
                    return Err(GripperError::new_err(
                        "the gripper's run has ended: no more sets",
                    ));
                }
                Err(false) => {}
            }
            py.check_signals()?;
            if deadline.is_some_and(|d| Instant::now() >= d) {
                return Err(PyTimeoutError::new_err(format!(
                    "no set within {} s",
                    timeout.unwrap_or_default()
                )));
            }
        }
    }

    /// Every set's report as it comes, until the run ends (or the gripper is closed).
    fn sets(slf: Py<Self>) -> SetIterator {
        SetIterator { gripper: slf }
    }

    /// Grasp and wait until the grasp ends; its result (the HTTP API's fields).
    /// `target_force_n`: N per finger, or `"auto"` (the grasp finds its own force).
    /// `KeyboardInterrupt` during the wait stops the fingers.
    #[pyo3(signature = (target_force_n=ForceArg::Newtons(1.5), speed_deg_s=15.0, timeout_s=20.0, fingers=None, current_limit_ma=None))]
    fn grasp<'py>(
        &self,
        py: Python<'py>,
        target_force_n: ForceArg,
        speed_deg_s: f64,
        timeout_s: f64,
        fingers: Option<Vec<usize>>,
        current_limit_ma: Option<f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.start_grasp(
            target_force_n,
            speed_deg_s,
            timeout_s,
            fingers,
            current_limit_ma,
        )?
        .wait(py, None)
    }

    /// Start a grasp and return at once; `wait` on the handle for its result.
    #[pyo3(signature = (target_force_n=ForceArg::Newtons(1.5), speed_deg_s=15.0, timeout_s=20.0, fingers=None, current_limit_ma=None))]
    fn start_grasp(
        &self,
        target_force_n: ForceArg,
        speed_deg_s: f64,
        timeout_s: f64,
        fingers: Option<Vec<usize>>,
        current_limit_ma: Option<f64>,
    ) -> PyResult<GraspHandle> {
        let (handle, request) = self.request(
            target_force_n,
            speed_deg_s,
            timeout_s,
            fingers,
            current_limit_ma,
        )?;
        let pending = handle.start_grasp(request).map_err(|e| gripper_error(&e))?;
        Ok(GraspHandle {
            pending: Mutex::new(Some(pending)),
            handle,
            outcome: Mutex::new(None),
        })
    }

    /// Open every finger.
    fn release(&self) -> PyResult<()> {
        self.with_running(|r| r.handle.release().map_err(|e| gripper_error(&e)))
    }

    /// Every finger holds where it is.
    fn stop(&self) -> PyResult<()> {
        self.with_running(|r| r.handle.stop().map_err(|e| gripper_error(&e)))
    }

    /// Every finger holds where it is at the minimum current.
    fn estop(&self) -> PyResult<()> {
        self.with_running(|r| r.handle.estop().map_err(|e| gripper_error(&e)))
    }

    /// Whether the gripper has been closed.
    #[getter]
    fn closed(&self) -> bool {
        self.running.lock().map_or(true, |r| r.is_none())
    }
}

impl Drop for Gripper {
    /// A gripper dropped without `close` still ends its run (safe state) and its thread.
    fn drop(&mut self) {
        if let Ok(mut running) = self.running.lock()
            && let Some(r) = running.take()
        {
            let _ = r.events.try_send(RuntimeEvent::Shutdown);
            let _ = r.thread.join();
        }
    }
}

/// `Gripper.sets()`: blocks for each set; ends with the run.
#[pyclass(module = "gelgrip")]
pub struct SetIterator {
    gripper: Py<Gripper>,
}

#[pymethods]
impl SetIterator {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Option<GripperSet>> {
        let queue = self.gripper.bind(py).borrow().queue.clone();
        loop {
            match py.detach(|| queue.pop(SLICE)) {
                Ok((set, dropped)) => return GripperSet::new(py, set, dropped).map(Some),
                Err(true) => return Ok(None),
                Err(false) => py.check_signals()?,
            }
        }
    }
}

/// A grasp in progress.
#[pyclass(module = "gelgrip")]
pub struct GraspHandle {
    pending: Mutex<Option<PendingGrasp>>,
    handle: GripperHandle,
    /// The result, once it came (JSON).
    outcome: Mutex<Option<String>>,
}

#[pymethods]
impl GraspHandle {
    /// The grasp's result, waiting at most `timeout` s of wall clock (None: until it ends);
    /// `TimeoutError` when it has not ended. `KeyboardInterrupt` stops the fingers.
    #[pyo3(signature = (timeout=None))]
    fn wait<'py>(&self, py: Python<'py>, timeout: Option<f64>) -> PyResult<Bound<'py, PyAny>> {
        if let Some(text) = self.outcome.lock().ok().and_then(|o| o.clone()) {
            return py.import("json")?.call_method1("loads", (text,));
        }
        let mut guard = self
            .pending
            .lock()
            .map_err(|_| GripperError::new_err("the grasp handle failed in another thread"))?;
        let Some(pending) = guard.as_mut() else {
            return Err(GripperError::new_err("the grasp gave no outcome"));
        };
        let Some(outcome) = wait_outcome(py, pending, &self.handle, timeout)? else {
            return Err(PyTimeoutError::new_err(format!(
                "the grasp has not ended within {} s",
                timeout.unwrap_or_default()
            )));
        };
        *guard = None;
        let text = serde_json::to_string(&outcome)
            .map_err(|e| errors::GelgripError::new_err(format!("outcome: {e}")))?;
        if let Ok(mut slot) = self.outcome.lock() {
            *slot = Some(text.clone());
        }
        py.import("json")?.call_method1("loads", (text,))
    }

    /// Whether the grasp has ended (its result is ready).
    fn done(&self) -> bool {
        if self.outcome.lock().is_ok_and(|o| o.is_some()) {
            return true;
        }
        let Ok(mut guard) = self.pending.lock() else {
            return true;
        };
        match guard.as_mut().and_then(PendingGrasp::try_outcome) {
            Some(Ok(outcome)) => {
                let text = serde_json::to_string(&outcome).ok();
                *guard = None;
                if let Ok(mut slot) = self.outcome.lock() {
                    *slot = text;
                }
                true
            }
            Some(Err(_)) => true,
            None => guard.is_none(),
        }
    }
}
