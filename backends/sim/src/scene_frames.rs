//! Frames of a scene in motion: each capture renders the pad's current indentation from the
//! shared [`World`](crate::world::World).
//!
//! An untouched pad serves its pre-rendered flat frames. A touched pad is rendered and
//! encoded only when its indentation changed (compared at 1 µm), so a steady hold costs
//! nothing per set and only moving contacts pay for rendering.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use bytes::Bytes;

use gelgrip_controller::layout::HandLayout;

use crate::config::SimConfig;
use crate::pool::{EncodeError, FramePool, SensorCamera};
use crate::scene::HeightMap;
use crate::world::SharedWorld;

/// Renders the world's pads.
#[derive(Debug)]
pub struct SceneFrames {
    world: SharedWorld,
    cameras: Vec<SensorCamera>,
    flat: FramePool,
    /// Per sensor: (indentation hash, its JPEG).
    cache: Vec<Option<(u64, Bytes)>>,
}

fn fingerprint(map: &HeightMap) -> u64 {
    let mut h = DefaultHasher::new();
    for d in &map.depth_mm {
        ((d * 1000.0).round() as i32).hash(&mut h);
    }
    h.finish()
}

impl SceneFrames {
    /// Frames of `world` for `layout`'s cameras.
    pub fn new(
        world: SharedWorld,
        layout: &HandLayout,
        cfg: &SimConfig,
    ) -> Result<Self, EncodeError> {
        let cameras: Vec<SensorCamera> = (0..layout.sensors.len())
            .filter_map(|i| SensorCamera::new(layout, i, cfg))
            .collect();
        Ok(Self {
            world,
            flat: FramePool::render_flat(layout, cfg)?,
            cache: vec![None; cameras.len()],
            cameras,
        })
    }

    /// The world.
    pub fn world(&self) -> &SharedWorld {
        &self.world
    }

    /// Advance the world to `now_us` and return every sensor's frame for capture `nth`.
    pub fn capture(&mut self, now_us: u64, nth: u64) -> Result<Vec<Bytes>, EncodeError> {
        let maps: Vec<Option<HeightMap>> = {
            let Ok(mut w) = self.world.lock() else {
                // A poisoned world cannot be stepped: serve untouched pads rather than stop.
                return Ok(self.flat_frames(nth));
            };
            w.advance_to(now_us);
            (0..self.cameras.len()).map(|s| w.height_map(s)).collect()
        };
        let mut out = Vec::with_capacity(maps.len());
        for (s, map) in maps.into_iter().enumerate() {
            let frame = match map {
                None => {
                    self.cache[s] = None;
                    self.flat.frame(s, nth).cloned().unwrap_or_default()
                }
                Some(map) => {
                    let key = fingerprint(&map);
                    match &self.cache[s] {
                        Some((k, jpeg)) if *k == key => jpeg.clone(),
                        _ => {
                            let jpeg = Bytes::from(self.cameras[s].jpeg(&map, nth)?);
                            self.cache[s] = Some((key, jpeg.clone()));
                            jpeg
                        }
                    }
                }
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
