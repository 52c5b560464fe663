//! What wakes the run loop: the embedding program's events, the real-clock deadline, the
//! dashboard's requests, and the hub's next event, as [`Runtime::run`](super::Runtime::run)
//! waits on them.

use std::sync::Arc;

use tokio::sync::mpsc;

use crate::clock::{Clock, ClockKind};
use crate::frame::{FrameSet, ReceivedFrame};
use crate::hub::HubError;
use crate::runtime::control::LoopCommand;

/// What the embedding program tells a running [`Runtime::run`](super::Runtime::run).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RuntimeEvent {
    /// Stop: bring the hardware to its safe state and end with `signal`.
    Shutdown,
    /// E-stop: hold at the minimum current and end with `estop`.
    Estop,
}

/// One wake-up of the loop.
pub(crate) enum Pass {
    Event(Option<RuntimeEvent>),
    Deadline,
    Tick,
    Request(Option<LoopCommand>),
    Step(Result<Option<FrameSet>, HubError>),
}

/// The next event; pending forever once the sender is gone (the run goes on).
pub(crate) async fn next_event(
    events: &mut mpsc::Receiver<RuntimeEvent>,
    open: bool,
) -> Option<RuntimeEvent> {
    if open {
        events.recv().await
    } else {
        std::future::pending().await
    }
}

/// The dashboard's next request; never without a dashboard. `None` once every sender is
/// gone.
pub(crate) async fn next_request(
    control: Option<&mut mpsc::Receiver<LoopCommand>>,
) -> Option<LoopCommand> {
    match control {
        Some(rx) => rx.recv().await,
        None => std::future::pending().await,
    }
}

/// Resolves at `deadline_us` on a real clock; never on a virtual one (whose time only moves
/// with the work, so the loop checks it after each pass instead).
pub(crate) async fn real_deadline(clock: Arc<dyn Clock>, deadline_us: Option<u64>) {
    match deadline_us {
        Some(d) if clock.kind() == ClockKind::Real => clock.sleep_until(d).await,
        _ => std::future::pending().await,
    }
}

/// Whether `frame` is in the set `step` emitted (it completed that set).
pub(crate) fn completes(step: &Result<Option<FrameSet>, HubError>, frame: &ReceivedFrame) -> bool {
    let Ok(Some(set)) = step else {
        return false;
    };
    set.frames.iter().any(|f| {
        f.frame.sensor == frame.frame.sensor && f.frame.trigger_seq == frame.frame.trigger_seq
    })
}
