//! The camera port: where emulated sensor boards (the CH347 chip emulator's, the CDC hub
//! emulator's) get their images. The simulator implements it, so an emulated hub serves the
//! same frames the simulated hub does, through the real wire protocols. And the press
//! camera port ([`PressCamera`]): where a calibration collects its ball presses from (the
//! simulator implements it too, so the calibration's plugins do not depend on it).

use bytes::Bytes;

/// The cameras of every sensor board.
pub trait BoardCameras: Send {
    /// Number of boards.
    fn boards(&self) -> usize;

    /// Board `board`'s JPEG for its `nth` capture, taken at host time `now_us`; an empty
    /// `Bytes` when the board has no camera (a dead board).
    fn capture(&mut self, board: usize, nth: u64, now_us: u64) -> Bytes;
}

/// Faults an emulated sensor board can be given (the CH347 and CDC hub emulators').
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BoardFaults {
    /// The board never answers (no ACK, no frame).
    pub dead: bool,
    /// Flip one bit of every `n`th frame on the wire (0 = never).
    pub corrupt_every: u64,
    /// Captures this long after its trigger, µs.
    pub capture_delay_us: u32,
}

/// Cameras whose every JPEG names its board and capture: byte 0 is the board, bytes 1–8 the
/// capture index (little-endian), the rest padding up to `jpeg_bytes`. Not an image: a
/// source for transport tests, which check that each frame arrives whole, once, and in its
/// set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PatternCameras {
    /// Number of boards.
    pub boards: usize,
    /// Size of every "JPEG", bytes (at least 9).
    pub jpeg_bytes: usize,
}

impl PatternCameras {
    /// Whether `jpeg` is board `board`'s capture `nth` (whole).
    pub fn matches(&self, jpeg: &[u8], board: usize, nth: u64) -> bool {
        jpeg.len() == self.jpeg_bytes.max(9)
            && jpeg[0] == board as u8
            && jpeg[1..9] == nth.to_le_bytes()
    }
}

impl BoardCameras for PatternCameras {
    fn boards(&self) -> usize {
        self.boards
    }

    fn capture(&mut self, board: usize, nth: u64, _now_us: u64) -> Bytes {
        let mut v = vec![board as u8];
        v.extend_from_slice(&nth.to_le_bytes());
        v.resize(self.jpeg_bytes.max(9), 0x5A);
        Bytes::from(v)
    }
}

/// Where a hub factory's emulated boards get their cameras from, configured by the
/// emulator's own config section (`[hub.ch347.emulator]`): the simulator implements it, so
/// a driver's crate can host its emulator without depending on the simulator.
pub trait CameraSource: Send + Sync + std::fmt::Debug {
    /// Check the emulator's section for `layout`.
    fn validate(
        &self,
        section: &crate::config::BackendSection,
        layout: &crate::layout::HandLayout,
    ) -> Result<(), crate::config::ConfigError>;

    /// The boards' cameras for `layout`, and the mean frame size they send, bytes (when
    /// known).
    fn open(
        &self,
        section: &crate::config::BackendSection,
        layout: &crate::layout::HandLayout,
    ) -> Result<(Box<dyn BoardCameras>, Option<f64>), String>;
}

/// A frame a [`PressCamera`] could not give, with the camera's own error.
#[derive(Debug, thiserror::Error)]
#[error("capturing frame {nth}: {detail}")]
pub struct CaptureError {
    /// The frame asked for.
    pub nth: u64,
    /// What went wrong.
    pub detail: String,
}

/// A sensor's camera that can be shown a ball pressed into its gel: what a calibration
/// collects its presses from. Frames are numbered (`nth`), so the same number gives the
/// same frame (noise included) on a deterministic camera.
pub trait PressCamera {
    /// Image width and height, px.
    fn size_px(&self) -> (usize, usize);
    /// Pixel size on the gel, mm.
    fn mm_per_px(&self) -> f64;
    /// Frame `nth` with nothing touching the gel, JPEG.
    fn untouched_jpeg(&self, nth: u64) -> Result<Vec<u8>, CaptureError>;
    /// Frame `nth` with a ball of `diameter_mm` pressed `depth_mm` deep at `centre_px`,
    /// JPEG.
    fn ball_press_jpeg(
        &self,
        centre_px: (f64, f64),
        diameter_mm: f64,
        depth_mm: f64,
        nth: u64,
    ) -> Result<Vec<u8>, CaptureError>;
}
