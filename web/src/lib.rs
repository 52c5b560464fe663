//! gelgrip's dashboard: an axum application, built as [`app`]`(state) -> Router`, that
//! serves the live state of a run (JSON and a Server-Sent-Events stream), each sensor's
//! camera as MJPEG (the hub's JPEG bytes forwarded, never re-encoded), depth and contact
//! images as PNG, the page itself (embedded in the binary), and the grasp API's commands.
//!
//! The run loop publishes into a [`live::Live`] and the routes read from it; commands go
//! through the controller's [`GripperHandle`](gelgrip_controller::gripper::GripperHandle),
//! and task and simulator requests through a [`control::LoopCommand`] channel to the run
//! loop.
//! Bound off loopback, every route but the login needs the token (`Authorization: Bearer
//! <token>`, or the session cookie the login sets); command endpoints are rate-limited,
//! except e-stop, which is never delayed.
//!
//! [`feed::Dashboard`] serves the app from a run and publishes into it as the runtime's
//! observer.
//!
//! [`calibrate::app`] serves the calibration view of `calibrate collect` on a hub instead,
//! with the same token scheme.

pub mod calibrate;
pub mod control;
pub mod feed;
mod grasps;
pub mod history;
mod limits;
pub mod live;
mod login;
mod routes;

pub use grasps::{DEFAULT_SPEED_DEG_S, DEFAULT_TIMEOUT_S, GoalProgress, MAX_TIMEOUT_S};
pub use live::{Live, Snapshot};
pub use routes::{AppState, app};
