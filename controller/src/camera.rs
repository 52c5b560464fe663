//! The camera port: where emulated sensor boards (the CH347 chip emulator's, the CDC hub
//! emulator's) get their images. The simulator implements it, so an emulated hub serves the
//! same frames the simulated hub does, through the real wire protocols.

use bytes::Bytes;

/// The cameras of every sensor board.
pub trait BoardCameras: Send {
    /// Number of boards.
    fn boards(&self) -> usize;

    /// Board `board`'s JPEG for its `nth` capture, taken at host time `now_us`; an empty
    /// `Bytes` when the board has no camera (a dead board).
    fn capture(&mut self, board: usize, nth: u64, now_us: u64) -> Bytes;
}
