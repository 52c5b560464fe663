//! The simulator as the camera port ([`BoardCameras`]) of emulated hubs (the CH347 chip
//! emulator's sensor boards, the CDC hub emulator): with a world, each capture renders the
//! pads' indentation at that instant; without, the built-in presses from the frame pool.
//!
//! Boards capture one by one; a broadcast trigger makes every board capture at the same
//! host time, so the world is rendered once per (time, capture) and shared by all boards.

use bytes::Bytes;

use gelgrip_controller::camera::{BoardCameras, CameraSource};
use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::layout::HandLayout;

use crate::config::SimConfig;
use crate::pool::{EncodeError, FramePool};
use crate::scene_frames::SceneFrames;
use crate::world::SharedWorld;

/// Simulated cameras for every sensor of a layout.
#[derive(Debug)]
pub struct SimCameras {
    boards: usize,
    pool: Option<FramePool>,
    scene: Option<SceneFrames>,
    /// The last rendering: (time, capture index) and every board's frame.
    last: Option<((u64, u64), Vec<Bytes>)>,
}

impl SimCameras {
    /// Cameras showing the built-in presses.
    pub fn presses(layout: &HandLayout, cfg: &SimConfig) -> Result<Self, EncodeError> {
        Ok(Self {
            boards: layout.sensors.len(),
            pool: Some(FramePool::render(layout, cfg)?),
            scene: None,
            last: None,
        })
    }

    /// Cameras showing `world`'s pads.
    pub fn of_world(
        layout: &HandLayout,
        cfg: &SimConfig,
        world: SharedWorld,
    ) -> Result<Self, EncodeError> {
        Ok(Self {
            boards: layout.sensors.len(),
            pool: None,
            scene: Some(SceneFrames::new(world, layout, cfg)?),
            last: None,
        })
    }
}

impl SimCameras {
    /// Mean JPEG size of the built-in presses (`None` when rendering a world), bytes.
    pub fn mean_jpeg_bytes(&self) -> Option<f64> {
        self.pool.as_ref().map(FramePool::mean_jpeg_bytes)
    }
}

impl BoardCameras for SimCameras {
    fn boards(&self) -> usize {
        self.boards
    }

    fn capture(&mut self, board: usize, nth: u64, now_us: u64) -> Bytes {
        if let Some(pool) = &self.pool {
            return pool.frame(board, nth).cloned().unwrap_or_default();
        }
        let key = (now_us, nth);
        if self.last.as_ref().is_none_or(|(k, _)| *k != key)
            && let Some(scene) = self.scene.as_mut()
        {
            let frames = scene.capture(now_us, nth).unwrap_or_default();
            self.last = Some((key, frames));
        }
        self.last
            .as_ref()
            .and_then(|(_, frames)| frames.get(board).cloned())
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::World;

    fn layout() -> HandLayout {
        crate::pool::tests::three_finger_layout()
    }

    fn cfg(layout: &HandLayout) -> SimConfig {
        crate::pool::tests::default_config(layout)
    }

    #[test]
    fn every_board_gets_a_jpeg_and_a_broadcast_renders_once() {
        let layout = layout();
        let cfg = cfg(&layout);
        let mut presses = SimCameras::presses(&layout, &cfg).expect("pool");
        assert_eq!(presses.boards(), 7);
        for b in 0..7 {
            let jpeg = presses.capture(b, 0, 0);
            assert_eq!(&jpeg[..2], &[0xFF, 0xD8], "board {b}: a JPEG");
        }
        let world = World::new(&layout, None).into_shared();
        let mut cams = SimCameras::of_world(&layout, &cfg, world).expect("scene");
        let a = cams.capture(0, 3, 1_000);
        let b = cams.capture(0, 3, 1_000);
        assert_eq!(a, b, "same capture, same frame");
        assert_eq!(&a[..2], &[0xFF, 0xD8]);
        assert!(cams.capture(9, 3, 1_000).is_empty(), "no such board");
    }
}

/// The simulator as a hub factory's [`CameraSource`]: its emulator section holds the
/// simulator's keys; the boards render `world` when there is one, else the built-in
/// presses.
#[derive(Debug, Clone, Default)]
pub struct SimCameraSource {
    world: Option<SharedWorld>,
}

impl SimCameraSource {
    /// Boards that render `world` (shared with the simulated servos), or the built-in
    /// presses without one.
    pub fn new(world: Option<SharedWorld>) -> Self {
        Self { world }
    }
}

impl CameraSource for SimCameraSource {
    fn validate(&self, section: &BackendSection, layout: &HandLayout) -> Result<(), ConfigError> {
        SimConfig::from_section(section, layout).map(|_| ())
    }

    fn open(
        &self,
        section: &BackendSection,
        layout: &HandLayout,
    ) -> Result<(Box<dyn BoardCameras>, Option<f64>), String> {
        let sim = SimConfig::from_section(section, layout).map_err(|e| e.to_string())?;
        let cameras = match &self.world {
            Some(w) => SimCameras::of_world(layout, &sim, w.clone()),
            None => SimCameras::presses(layout, &sim),
        }
        .map_err(|e| e.to_string())?;
        let mean = cameras.mean_jpeg_bytes();
        Ok((Box::new(cameras), mean))
    }
}
