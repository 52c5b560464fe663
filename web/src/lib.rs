//! gelgrip's dashboard: an axum application, built as [`app`]`(state) -> Router`, that
//! serves the live state of a run (JSON and a Server-Sent-Events stream), each sensor's
//! camera as MJPEG (the hub's JPEG bytes forwarded, never re-encoded), depth and contact
//! images as PNG, the page itself (embedded in the binary), and the grasp API's commands.
//!
//! The run loop publishes into a [`live::Live`] and the routes read from it; commands go
//! through the controller's [`GripperHandle`](gelgrip_controller::gripper::GripperHandle),
//! and task and simulator requests through a [`control::LoopCommand`] channel to the run
//! loop.
//! Command endpoints need `Authorization: Bearer <token>` when the server is bound off
//! loopback, and are rate-limited, except e-stop, which is never delayed.

pub mod control;
mod limits;
pub mod live;
mod routes;

pub use live::{Live, Snapshot};
pub use routes::{AppState, app};
