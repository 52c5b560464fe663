//! Frames of a scene in motion: each capture renders the pad's current indentation from the
//! shared [`World`](crate::world::World).
//!
//! An untouched pad serves its pre-rendered flat frames. A touched pad is rendered and
//! encoded only when its indentation changed (compared at 5 µm), so a steady hold costs
//! nothing per set and only moving contacts pay for rendering.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use bytes::Bytes;
use rayon::prelude::*;

use gelgrip_controller::layout::HandLayout;

use crate::config::SimConfig;
use crate::pool::{EncodeError, FramePool, SceneCamera, SensorCamera};
use crate::scene::HeightMap;
use crate::world::SharedWorld;

/// Renders the world's pads.
#[derive(Debug)]
pub struct SceneFrames {
    world: SharedWorld,
    cameras: Vec<SceneCamera>,
    flat: FramePool,
    /// Per sensor: (indentation hash, its JPEG).
    cache: Vec<Option<(u64, Bytes)>>,
}

/// Indentation changes smaller than this are invisible under the camera noise (σ ≈ 10
/// grey levels), so they reuse the last frame, µm.
const KEY_STEP_UM: f32 = 5.0;

fn fingerprint(map: &HeightMap) -> u64 {
    let mut h = DefaultHasher::new();
    for d in &map.depth_mm {
        ((d * (1000.0 / KEY_STEP_UM)).round() as i32).hash(&mut h);
    }
    h.finish()
}

impl SceneFrames {
    /// The faults injected at run time, per sensor (`None`: the configured ones).
    pub fn injected_faults(&self, sensors: usize) -> Vec<Option<crate::config::SensorFaults>> {
        match self.world.lock() {
            Ok(w) => (0..sensors)
                .map(|i| w.injected_faults(i).cloned())
                .collect(),
            Err(_) => vec![None; sensors],
        }
    }

    /// Whether the world has the hub unplugged at host time `at_us`.
    pub fn hub_unplugged(&self, at_us: u64) -> bool {
        self.world.lock().is_ok_and(|w| w.hub_unplugged(at_us))
    }

    /// Frames of `world` for `layout`'s cameras.
    pub fn new(
        world: SharedWorld,
        layout: &HandLayout,
        cfg: &SimConfig,
    ) -> Result<Self, EncodeError> {
        let cameras: Vec<SceneCamera> = (0..layout.sensors.len())
            .filter_map(|i| SensorCamera::new(layout, i, cfg))
            .map(SceneCamera::new)
            .collect();
        Ok(Self {
            world,
            flat: FramePool::render_flat(layout, cfg)?,
            cache: vec![None; cameras.len()],
            cameras,
        })
    }

    /// Advance the world to `now_us` and return every sensor's frame for capture `nth`.
    /// Height maps and JPEGs of the touched pads are made in parallel.
    pub fn capture(&mut self, now_us: u64, nth: u64) -> Result<Vec<Bytes>, EncodeError> {
        let maps: Vec<Option<HeightMap>> = {
            let Ok(mut w) = self.world.lock() else {
                // A poisoned world cannot be stepped: serve untouched pads rather than stop.
                return Ok(self.flat_frames(nth));
            };
            w.advance_to(now_us);
            let w = &*w;
            (0..self.cameras.len())
                .into_par_iter()
                .map(|s| w.height_map(s))
                .collect()
        };
        let keyed: Vec<Option<(u64, HeightMap)>> = maps
            .into_iter()
            .map(|m| m.map(|m| (fingerprint(&m), m)))
            .collect();
        let fresh: Vec<Option<Bytes>> = keyed
            .par_iter()
            .enumerate()
            .map(|(s, k)| match (k, &self.cache[s]) {
                (Some((key, _)), Some((cached, _))) if key == cached => Ok(None),
                (Some((_, map)), _) => self.cameras[s].jpeg(map, nth).map(|j| Some(Bytes::from(j))),
                (None, _) => Ok(None),
            })
            .collect::<Result<_, _>>()?;
        let mut out = Vec::with_capacity(keyed.len());
        for (s, (k, new)) in keyed.into_iter().zip(fresh).enumerate() {
            let frame = match (k, new) {
                (None, _) => {
                    self.cache[s] = None;
                    self.flat.frame(s, nth).cloned().unwrap_or_default()
                }
                (Some((key, _)), Some(jpeg)) => {
                    self.cache[s] = Some((key, jpeg.clone()));
                    jpeg
                }
                (Some(_), None) => self.cache[s]
                    .as_ref()
                    .map(|(_, j)| j.clone())
                    .unwrap_or_default(),
            };
            out.push(frame);
        }
        Ok(out)
    }

    fn flat_frames(&self, nth: u64) -> Vec<Bytes> {
        (0..self.cameras.len())
            .map(|s| self.flat.frame(s, nth).cloned().unwrap_or_default())
            .collect()
    }
}
