//! Frames of a scene in motion: each capture renders the pad's current indentation from the
//! shared [`World`](crate::world::World).
//!
//! An untouched pad serves its pre-rendered flat frames. A touched pad keeps, per
//! indentation (compared at 5 µm), up to `noise_pool` frames with different noise and cycles
//! through them by capture count, like the flat frames: a steady hold costs nothing per set
//! once its variants are rendered, only moving contacts pay for rendering, and consecutive
//! frames never share their noise (a real camera draws it afresh; one frame reused for many
//! captures would turn the noise into a bias that a controller's average cannot remove).

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};

use bytes::Bytes;
use rayon::prelude::*;

use gelgrip_controller::layout::HandLayout;

use crate::config::SimConfig;
use crate::markers::GelShear;
use crate::pool::{EncodeError, FramePool, SceneCamera, SensorCamera};
use crate::scene::HeightMap;
use crate::world::SharedWorld;

/// Renders the world's pads.
#[derive(Debug)]
pub struct SceneFrames {
    world: SharedWorld,
    cameras: Vec<SceneCamera>,
    flat: FramePool,
    /// Per sensor: the indentation's hash and its frames by noise variant.
    cache: Vec<Option<Variants>>,
    /// Noise variants kept per indentation.
    pool: usize,
}

/// One indentation's frames, each with a different noise.
#[derive(Debug, Clone)]
struct Variants {
    key: u64,
    frames: Vec<Option<Bytes>>,
}

impl Variants {
    fn get(&self, key: u64, variant: usize) -> Option<&Bytes> {
        (self.key == key)
            .then(|| self.frames.get(variant).and_then(Option::as_ref))
            .flatten()
    }
}

/// Indentation changes smaller than this are invisible under the camera noise (σ ≈ 10
/// grey levels), so they reuse the last frame, µm.
const KEY_STEP_UM: f32 = 5.0;

/// A touched pad: its indentation and, under tangential load, its gel's shear.
#[derive(Debug, Clone)]
pub struct TouchedPad {
    /// The gel's indentation.
    pub map: HeightMap,
    /// How its surface moves (`None`: no tangential load).
    pub shear: Option<GelShear>,
}

/// Shear changes smaller than this move a marker by a hundredth of a pixel at most, so
/// they reuse the last frame, mm.
const SHEAR_STEP_MM: f64 = 5e-4;

fn fingerprint(pad: &TouchedPad) -> u64 {
    let mut h = DefaultHasher::new();
    for d in &pad.map.depth_mm {
        ((d * (1000.0 / KEY_STEP_UM)).round() as i32).hash(&mut h);
    }
    if let Some(s) = &pad.shear {
        let t = &s.traction;
        let quantum = |v: f64, step: f64| (v / step).round() as i64;
        for v in [
            t.shift_mm,
            t.stick_ratio * t.contact_radius_mm,
            t.contact_radius_mm,
        ] {
            quantum(v, SHEAR_STEP_MM).hash(&mut h);
        }
        for v in [s.centre_px.0, s.centre_px.1, s.direction.0, s.direction.1] {
            quantum(v, 0.01).hash(&mut h);
        }
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
            pool: cfg.noise_pool.max(1),
            cameras,
        })
    }

    /// Advance the world to `now_us` and return every sensor's frame for capture `nth`.
    /// Height maps and JPEGs of the touched pads are made in parallel.
    pub fn capture(&mut self, now_us: u64, nth: u64) -> Result<Vec<Bytes>, EncodeError> {
        let maps = height_maps(&self.world, self.cameras.len(), now_us);
        self.render(maps, nth)
    }

    /// The world this renders.
    pub fn world(&self) -> &SharedWorld {
        &self.world
    }

    /// Every sensor's frame for capture `nth` from its height map (`None`: untouched),
    /// `maps` from [`height_maps`] (`None`: the world could not be read; every pad is
    /// served untouched). The JPEGs of the touched pads are made in parallel.
    pub fn render(
        &mut self,
        maps: Option<Vec<Option<TouchedPad>>>,
        nth: u64,
    ) -> Result<Vec<Bytes>, EncodeError> {
        let Some(maps) = maps else {
            return Ok(self.flat_frames(nth));
        };
        // Shear shows only through markers: a plain gel's frame does not depend on it.
        let keyed: Vec<Option<(u64, TouchedPad)>> = maps
            .into_iter()
            .zip(&self.cameras)
            .map(|(m, camera)| {
                m.map(|mut m| {
                    m.shear = m.shear.filter(|_| camera.has_markers());
                    (fingerprint(&m), m)
                })
            })
            .collect();
        let variant = (nth % self.pool as u64) as usize;
        let fresh: Vec<Option<Bytes>> = keyed
            .par_iter()
            .enumerate()
            .map(|(s, k)| match k {
                Some((key, pad)) => match self.cache[s].as_ref().and_then(|v| v.get(*key, variant))
                {
                    Some(_) => Ok(None),
                    None => self.cameras[s]
                        .jpeg(&pad.map, pad.shear.as_ref(), nth)
                        .map(|j| Some(Bytes::from(j))),
                },
                None => Ok(None),
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
                    let mut entry = match self.cache[s].take() {
                        Some(v) if v.key == key => v,
                        _ => Variants {
                            key,
                            frames: vec![None; self.pool],
                        },
                    };
                    entry.frames[variant] = Some(jpeg.clone());
                    self.cache[s] = Some(entry);
                    jpeg
                }
                (Some((key, _)), None) => self.cache[s]
                    .as_ref()
                    .and_then(|v| v.get(key, variant))
                    .cloned()
                    .unwrap_or_default(),
            };
            out.push(frame);
        }
        Ok(out)
    }

    /// Sensors rendered.
    pub fn sensors(&self) -> usize {
        self.cameras.len()
    }

    fn flat_frames(&self, nth: u64) -> Vec<Bytes> {
        (0..self.cameras.len())
            .map(|s| self.flat.frame(s, nth).cloned().unwrap_or_default())
            .collect()
    }
}

/// Advance `world` to `now_us` and take the height map and shear of each of its first
/// `sensors` pads (`None`: untouched), in parallel; `None` when the world is poisoned (it
/// cannot be stepped).
pub fn height_maps(
    world: &SharedWorld,
    sensors: usize,
    now_us: u64,
) -> Option<Vec<Option<TouchedPad>>> {
    let mut w = world.lock().ok()?;
    w.advance_to(now_us);
    let w = &*w;
    Some(
        (0..sensors)
            .into_par_iter()
            .map(|s| {
                w.height_map(s).map(|map| TouchedPad {
                    map,
                    shear: w.gel_shear(s),
                })
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene_spec::SceneSpec;
    use crate::world::World;
    use gelgrip_controller::actuator::MotorCommand;

    #[test]
    fn a_still_contact_cycles_through_noise_variants_and_never_repeats_the_last_frame() {
        let layout = HandLayout::from_toml(
            "three-finger.toml",
            include_str!("../../../configs/layouts/three-finger.toml"),
        )
        .expect("layout");
        let scene = SceneSpec::from_toml(
            "tennis-ball.toml",
            include_str!("../../../configs/scenes/tennis-ball.toml"),
            &layout,
        )
        .expect("scene");
        let mut world = World::new(&layout, Some(scene));
        for f in 0..world.fingers() {
            world.set_command(
                f,
                MotorCommand {
                    torque_on: true,
                    goal_position_deg: 180.0,
                    goal_current_ma: 300.0,
                    profile_velocity_rpm: 0.0,
                },
            );
        }
        // Settle the squeeze, then capture the same instant again and again.
        let settled_us = 4_000_000;
        for t_us in (0..=settled_us).step_by(100_000) {
            world.advance_to(t_us);
        }
        let cfg = crate::pool::tests::default_config(&layout);
        let pool = cfg.noise_pool as u64;
        let mut frames = SceneFrames::new(world.into_shared(), &layout, &cfg).expect("frames");
        frames.capture(settled_us, 0).expect("capture");
        let touched: Vec<usize> = {
            let w = frames.world.lock().expect("world");
            (0..layout.sensors.len())
                .filter(|s| w.height_map(*s).is_some())
                .collect()
        };
        assert!(!touched.is_empty(), "the ball is touched");
        let shots: Vec<Vec<Bytes>> = (1..=2 * pool)
            .map(|nth| frames.capture(settled_us, nth).expect("capture"))
            .collect();
        for s in touched {
            for n in 1..shots.len() {
                assert_ne!(shots[n][s], shots[n - 1][s], "sensor {s}: capture {n}");
            }
            for n in 0..pool as usize {
                let (a, b) = (&shots[n][s], &shots[n + pool as usize][s]);
                assert_eq!(a.as_ptr(), b.as_ptr(), "sensor {s}: variant {n} reused");
            }
        }
    }
}
