//! Known weights on the emulated hubs' sensors: what `gelgrip calibrate force` asks a user
//! to place on a real sensor, for the CDC hub emulator (`gelgrip emulate hub
//! --weights-on-stdin`).
//!
//! A weight rests on the pad through a ball indenter of [`WEIGHT_INDENTER_MM`] centred on
//! the pad: the emulator finds the indentation depth at which the simulator's gel law (the
//! same one that loads the fingers) carries the weight, and the board then shows that press
//! (with fresh camera noise per capture) until the weight is changed. Boards without a
//! weight show the untouched gel.

use std::sync::{Arc, Mutex, PoisonError};

use bytes::Bytes;
use thiserror::Error;

use gelgrip_controller::camera::BoardCameras;
use gelgrip_controller::fusion::{STANDARD_GRAVITY_M_S2, weight_force_n};
use gelgrip_controller::layout::HandLayout;

use crate::config::SimConfig;
use crate::contact::pressure_n_per_mm2;
use crate::pool::{EncodeError, SensorCamera};
use crate::scene::HeightMap;

/// Diameter of the ball a weight rests on, mm (a common calibration indenter).
pub const WEIGHT_INDENTER_MM: f64 = 30.0;
/// Deepest indentation a weight may make, mm (the gel is about 2 mm thick).
const MAX_DEPTH_MM: f64 = 1.5;

/// Why a weight could not be placed.
#[derive(Debug, Error)]
pub enum WeightError {
    /// No such board.
    #[error("no sensor board {board} (the hub has {boards})")]
    NoBoard {
        /// The board asked for.
        board: usize,
        /// Boards present.
        boards: usize,
    },
    /// Not a usable weight.
    #[error("a weight of {grams} g is not a load this sensor can carry (0 to {max_grams:.0} g)")]
    OutOfRange {
        /// The weight asked for, g.
        grams: f64,
        /// The heaviest the pad carries within its depth range, g.
        max_grams: f64,
    },
    /// Not a ball press the pad can show.
    #[error("not a ball press this sensor can show: {0}")]
    BadPress(String),
    /// Rendering the press failed.
    #[error(transparent)]
    Encode(#[from] EncodeError),
}

/// A calibration ball press in place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallPress {
    /// Centre, px.
    pub center_x_px: f64,
    /// Centre, px.
    pub center_y_px: f64,
    /// Ball diameter, mm.
    pub ball_mm: f64,
    /// Indentation, mm.
    pub depth_mm: f64,
    /// Radius of the contact circle, px (the press dataset's label).
    pub contact_radius_px: f64,
}

/// A weight in place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeightPress {
    /// The weight, g.
    pub grams: f64,
    /// Its load, N.
    pub force_n: f64,
    /// The indentation that carries it, mm.
    pub depth_mm: f64,
}

/// Each board's frames, cycled by capture number (shared by the cameras and the control).
type BoardFrames = Arc<Mutex<Vec<Vec<Bytes>>>>;

/// The cameras of a hub whose sensors carry known weights ([`BoardCameras`]).
#[derive(Debug)]
pub struct WeightedCameras {
    frames: BoardFrames,
}

/// Places and removes weights on a [`WeightedCameras`]' boards.
#[derive(Debug, Clone)]
pub struct WeightControl {
    frames: BoardFrames,
    cameras: Vec<SensorCamera>,
    noise_pool: u64,
    shown: Arc<std::sync::atomic::AtomicU64>,
}

/// Cameras for every sensor of `layout`, all untouched, and their control.
pub fn weighted_cameras(
    layout: &HandLayout,
    cfg: &SimConfig,
) -> Result<(WeightedCameras, WeightControl), WeightError> {
    let cameras: Vec<SensorCamera> = (0..layout.sensors.len())
        .filter_map(|i| SensorCamera::new(layout, i, cfg))
        .collect();
    let control = WeightControl {
        frames: Arc::new(Mutex::new(vec![Vec::new(); cameras.len()])),
        cameras,
        noise_pool: cfg.noise_pool.max(1) as u64,
        shown: Arc::default(),
    };
    for board in 0..control.cameras.len() {
        control.place(board, 0.0)?;
    }
    Ok((
        WeightedCameras {
            frames: control.frames.clone(),
        },
        control,
    ))
}

impl WeightControl {
    /// Rest `grams` on board `board` (0 removes the weight); returns the press.
    pub fn place(&self, board: usize, grams: f64) -> Result<WeightPress, WeightError> {
        let cam = self.cameras.get(board).ok_or(WeightError::NoBoard {
            board,
            boards: self.cameras.len(),
        })?;
        let force_n = weight_force_n(grams);
        let max_n = load_n(cam, MAX_DEPTH_MM);
        if !grams.is_finite() || grams < 0.0 || force_n > max_n {
            return Err(WeightError::OutOfRange {
                grams,
                max_grams: max_n / STANDARD_GRAVITY_M_S2 * 1000.0,
            });
        }
        let depth_mm = depth_for(cam, force_n);
        let map = press(cam, depth_mm);
        let frames = (0..self.noise_pool)
            .map(|k| cam.jpeg(&map, 5_000_000 + k).map(Bytes::from))
            .collect::<Result<Vec<_>, _>>()?;
        self.frames.lock().unwrap_or_else(PoisonError::into_inner)[board] = frames;
        Ok(WeightPress {
            grams,
            force_n,
            depth_mm,
        })
    }
}

impl WeightControl {
    /// Press a ball of `ball_mm` `depth_mm` deep at `centre` (px) on board `board`, shown
    /// until the next press, weight or lift ([`WeightControl::place`] with 0 g lifts it).
    /// Each press gets camera noise of its own.
    pub fn press_ball(
        &self,
        board: usize,
        (cx, cy): (f64, f64),
        ball_mm: f64,
        depth_mm: f64,
    ) -> Result<BallPress, WeightError> {
        let cam = self.cameras.get(board).ok_or(WeightError::NoBoard {
            board,
            boards: self.cameras.len(),
        })?;
        let r_mm = ball_mm / 2.0;
        let finite = [cx, cy, ball_mm, depth_mm].iter().all(|v| v.is_finite());
        if !finite || ball_mm <= 0.0 || !(0.0..=r_mm.min(MAX_DEPTH_MM)).contains(&depth_mm) {
            return Err(WeightError::BadPress(format!(
                "ball {ball_mm} mm, {depth_mm} mm deep: expected a ball over 0 mm pressed 0 to {:.2} mm deep",
                r_mm.min(MAX_DEPTH_MM)
            )));
        }
        let (w, h) = (cam.width as f64, cam.height as f64);
        if !(0.0..w).contains(&cx) || !(0.0..h).contains(&cy) {
            return Err(WeightError::BadPress(format!(
                "centre ({cx}, {cy}) px is off the {w}x{h} px pad"
            )));
        }
        let map = HeightMap::ball_press(
            cam.width,
            cam.height,
            cam.mm_per_px,
            (cx, cy),
            ball_mm,
            depth_mm,
        );
        let nth = self
            .shown
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let first = 6_000_000 + nth * self.noise_pool;
        let frames = (0..self.noise_pool)
            .map(|k| cam.jpeg(&map, first + k).map(Bytes::from))
            .collect::<Result<Vec<_>, _>>()?;
        self.frames.lock().unwrap_or_else(PoisonError::into_inner)[board] = frames;
        Ok(BallPress {
            center_x_px: cx,
            center_y_px: cy,
            ball_mm,
            depth_mm,
            contact_radius_px: (r_mm * r_mm - (r_mm - depth_mm).powi(2)).max(0.0).sqrt()
                / cam.mm_per_px,
        })
    }
}

/// The indenter pressed `depth_mm` into the centre of `cam`'s pad.
fn press(cam: &SensorCamera, depth_mm: f64) -> HeightMap {
    let centre = (cam.width as f64 / 2.0, cam.height as f64 / 2.0);
    HeightMap::ball_press(
        cam.width,
        cam.height,
        cam.mm_per_px,
        centre,
        WEIGHT_INDENTER_MM,
        depth_mm,
    )
}

/// The gel's load at indentation `depth_mm`, N.
fn load_n(cam: &SensorCamera, depth_mm: f64) -> f64 {
    if depth_mm <= 0.0 {
        return 0.0;
    }
    let px_mm2 = cam.mm_per_px * cam.mm_per_px;
    press(cam, depth_mm)
        .depth_mm
        .iter()
        .map(|d| pressure_n_per_mm2(f64::from(*d)) * px_mm2)
        .sum()
}

/// The indentation carrying `force_n` (bisection: the load grows with depth), mm.
fn depth_for(cam: &SensorCamera, force_n: f64) -> f64 {
    if force_n <= 0.0 {
        return 0.0;
    }
    let (mut lo, mut hi) = (0.0, MAX_DEPTH_MM);
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if load_n(cam, mid) < force_n {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

impl BoardCameras for WeightedCameras {
    fn boards(&self) -> usize {
        self.frames
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .len()
    }

    fn capture(&mut self, board: usize, nth: u64, _now_us: u64) -> Bytes {
        let frames = self.frames.lock().unwrap_or_else(PoisonError::into_inner);
        frames
            .get(board)
            .and_then(|f| f.get((nth % f.len().max(1) as u64) as usize))
            .cloned()
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout() -> HandLayout {
        crate::pool::tests::three_finger_layout()
    }

    fn cfg() -> SimConfig {
        crate::pool::tests::default_config(&layout())
    }

    #[test]
    fn a_weight_is_carried_by_the_gel_law_and_shown_only_on_its_board() {
        let (mut cams, control) = weighted_cameras(&layout(), &cfg()).expect("cams");
        let flat = cams.capture(1, 0, 0);
        let p = control.place(0, 100.0).expect("100 g");
        assert!((p.force_n - 0.980_665).abs() < 1e-9);
        let cam = &control.cameras[0];
        let carried = load_n(cam, p.depth_mm);
        assert!((carried - p.force_n).abs() / p.force_n < 1e-3, "{carried}");
        assert!(p.depth_mm > 0.1 && p.depth_mm < 1.5, "{p:?}");
        assert_ne!(cams.capture(0, 0, 0), cams.capture(0, 1, 0), "fresh noise");
        assert_eq!(cams.capture(1, 0, 0), flat, "board 1 untouched");
        assert_eq!(cams.boards(), 7);
        let heavier = control.place(0, 200.0).expect("200 g");
        assert!(heavier.depth_mm > p.depth_mm);
        assert_eq!(control.place(0, 0.0).expect("removed").depth_mm, 0.0);
    }

    #[test]
    fn impossible_weights_and_boards_are_errors() {
        let (_, control) = weighted_cameras(&layout(), &cfg()).expect("cams");
        for g in [-1.0, f64::NAN, f64::INFINITY, 1e6] {
            let err = control.place(0, g).expect_err("out of range");
            assert!(matches!(err, WeightError::OutOfRange { .. }), "{g}: {err}");
        }
        let err = control.place(7, 10.0).expect_err("no board 7");
        assert!(err.to_string().contains("no sensor board 7"), "{err}");
    }

    #[test]
    fn a_ball_press_is_shown_on_request_and_lifted() {
        let (mut cams, control) = weighted_cameras(&layout(), &cfg()).expect("cams");
        let flat = cams.capture(0, 0, 0);
        let p = control
            .press_ball(0, (100.0, 80.0), 6.0, 0.5)
            .expect("press");
        let expected = (9.0f64 - 2.5 * 2.5).sqrt() / control.cameras[0].mm_per_px;
        assert!((p.contact_radius_px - expected).abs() < 1e-9, "{p:?}");
        assert_ne!(cams.capture(0, 0, 0), flat);
        for bad in [(1e6, 80.0, 0.5), (100.0, 80.0, 4.0), (f64::NAN, 80.0, 0.5)] {
            let err = control
                .press_ball(0, (bad.0, bad.1), 6.0, bad.2)
                .expect_err("bad");
            assert!(matches!(err, WeightError::BadPress(_)), "{err}");
        }
        control.place(0, 0.0).expect("lifted");
        assert_eq!(cams.capture(0, 0, 0).len(), flat.len());
    }
}
