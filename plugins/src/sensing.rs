//! The tactile pipelines as the runtime's [`Sensing`] port: one [`SensorPipeline`] per
//! sensor, behind the controller's per-sensor readings.
//!
//! Each frame is worked on as it arrives ([`Tactile::frame_arrived`], streaming: see
//! [`crate::pipeline::stream`]), before the gate decides on its set; each gated set goes
//! through [`Tactile::process`], which takes what was worked on ahead for its very frames and
//! processes the rest, the sensors in parallel, and comes out as the controller's
//! per-sensor readings (`None` for a sensor whose frame failed).
//!
//! On a hardware hub the references come from the first live sets, untouched
//! ([`Tactile::new`] with `reference_from_live`). What builds the pipelines from a config
//! (model files, the simulator's cached self-calibration) is the composition root's.

use gelgrip_controller::frame::{FrameSet, ReceivedFrame};
use gelgrip_controller::fusion::SensorReading;
use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::runtime::ports::Sensing;
use gelgrip_controller::runtime::report::{DepthWindow, DepthWindows};

use crate::contact::ContactSummary;
use crate::pipeline::stream::{FrameKey, StreamingSensors};
use crate::pipeline::{Needs, SensorPipeline};

/// No-contact frames averaged into each sensor's reference (live: the first sets).
pub const REFERENCE_FRAMES: u64 = 12;

/// Every sensor's pipeline.
pub struct Tactile {
    pipes: StreamingSensors,
    geometry: Vec<(f64, f64, f64)>,
    results: Vec<Result<ContactSummary, crate::pipeline::PipelineError>>,
    /// On a hardware hub, each sensor's untouched frames gathered so far for its reference
    /// (`None` once referenced, and on the simulator).
    pending_reference: Option<Vec<Vec<Vec<u8>>>>,
}

impl Tactile {
    /// The run's sensing on `pipes`, one per sensor of `layout` in its order. With
    /// `reference_from_live` (a hardware hub) the references are the first
    /// [`REFERENCE_FRAMES`] sets [`Tactile::process`] receives (the gripper starts open,
    /// nothing touching): until then every reading is `None`, which holds the fingers.
    /// Otherwise each pipeline is referenced already.
    pub fn new(pipes: Vec<SensorPipeline>, layout: &HandLayout, reference_from_live: bool) -> Self {
        let geometry = sensor_geometry(layout);
        let n = pipes.len();
        Self {
            pipes: StreamingSensors::new(pipes, Needs::DEPTH),
            geometry,
            results: (0..n).map(|_| Ok(ContactSummary::default())).collect(),
            pending_reference: reference_from_live.then(|| vec![Vec::new(); n]),
        }
    }

    /// Sets still to gather for the live references (0 on the simulator and once taken).
    pub fn reference_sets_missing(&self) -> usize {
        self.pending_reference.as_ref().map_or(0, |p| {
            (REFERENCE_FRAMES as usize).saturating_sub(p.first().map_or(0, Vec::len))
        })
    }

    /// Take `set` toward the live references (a run does this before its loop, so the
    /// one-time reference does not stall the loop; a replay, in [`Tactile::process`]).
    pub fn offer_reference(&mut self, set: &FrameSet) {
        let mut frames: Vec<&[u8]> = Vec::with_capacity(self.pipes.len());
        for (i, f) in set.frames.iter().enumerate() {
            if usize::from(f.frame.sensor.0) == i {
                frames.push(f.frame.jpeg.as_ref());
            }
        }
        if frames.len() == self.pipes.len() {
            self.gather_reference(&frames);
        }
    }

    /// Gather `frames` toward the live references; true while still gathering.
    fn gather_reference(&mut self, frames: &[&[u8]]) -> bool {
        let Some(pending) = self.pending_reference.as_mut() else {
            return false;
        };
        for (kept, frame) in pending.iter_mut().zip(frames) {
            kept.push(frame.to_vec());
        }
        if pending.first().map_or(0, Vec::len) < REFERENCE_FRAMES as usize {
            return true;
        }
        // The sensors in parallel, as in process_set.
        let pipes = &self.pipes;
        std::thread::scope(|scope| {
            for (i, kept) in pending.iter().enumerate() {
                scope.spawn(move || {
                    let quiet: Vec<&[u8]> = kept.iter().map(Vec::as_slice).collect();
                    let done = pipes.with_pipe_mut(i, |pipe| pipe.calibrate(&quiet));
                    if let Some(Err(e)) = done {
                        tracing::error!(
                            sensor = i,
                            "reference from live frames failed: {e}; its finger holds"
                        );
                    }
                });
            }
        });
        tracing::info!(
            sets = REFERENCE_FRAMES,
            "sensors referenced on live untouched frames"
        );
        self.pending_reference = None;
        true
    }

    /// Sensor `i`'s last reconstructed depth window (mm, row-major), where it lies in the
    /// processed frame, and the depth above which a pixel counts as contact, mm.
    /// `None` while the pipeline's buffers hold a frame worked on ahead of its set.
    pub fn depth_window(&self, i: usize) -> Option<DepthWindow> {
        self.pipes
            .with_committed_pipe(i, |pipe| {
                let (depth, (x0, y0, w, h)) = pipe.last_depth_mm();
                if w == 0 || h == 0 {
                    return None;
                }
                let threshold = pipe.noise().map_or(0.05, |n| n.depth_threshold_mm);
                Some(DepthWindow {
                    depth_mm: depth.to_vec(),
                    width: w,
                    height: h,
                    origin_px: (x0, y0),
                    frame_px: pipe.size(),
                    contact_mm: threshold,
                })
            })
            .flatten()
    }

    /// A frame has arrived, before the gate decides on its set: work on it now (nothing
    /// while the live references are still being gathered).
    pub fn frame_arrived(&self, frame: &ReceivedFrame) {
        if self.pending_reference.is_some() {
            return;
        }
        self.pipes.arrive(
            usize::from(frame.frame.sensor.0),
            FrameKey {
                trigger_seq: frame.frame.trigger_seq,
                jpeg: frame.frame.jpeg.clone(),
            },
        );
    }

    /// Process one gated set into per-sensor readings: `None` for a sensor whose pipeline
    /// failed, and for one the gate left out of the set (excluded).
    pub fn process(&mut self, set: &FrameSet) -> Vec<Option<SensorReading>> {
        let n = self.pipes.len();
        let mut by_sensor: Vec<Option<FrameKey>> = vec![None; n];
        for f in &set.frames {
            if let Some(slot) = by_sensor.get_mut(usize::from(f.frame.sensor.0)) {
                *slot = Some(FrameKey {
                    trigger_seq: f.frame.trigger_seq,
                    jpeg: f.frame.jpeg.clone(),
                });
            }
        }
        if self.pending_reference.is_some() {
            if by_sensor.iter().all(Option::is_some) {
                let frames: Vec<&[u8]> = by_sensor.iter().flatten().map(|k| &k.jpeg[..]).collect();
                self.gather_reference(&frames);
            }
            return vec![None; n];
        }
        self.pipes.process(&by_sensor, &mut self.results);
        self.results
            .iter()
            .zip(&self.geometry)
            .zip(&by_sensor)
            .map(|((r, geometry), frame)| {
                frame.as_ref()?;
                Some(sensor_reading(r.as_ref().ok()?, *geometry))
            })
            .collect()
    }
}

/// Each of `layout`'s sensors' image width and height (px) and pixel size (mm/px), in
/// layout order: what [`sensor_reading`] places a contact with.
pub fn sensor_geometry(layout: &HandLayout) -> Vec<(f64, f64, f64)> {
    layout
        .sensors
        .iter()
        .map(|spec| {
            let (w, h) = (spec.resolution.width_px, spec.resolution.height_px);
            (f64::from(w), f64::from(h), spec.mm_per_px)
        })
        .collect()
}

/// The reading the controller fuses from a pipeline's summary `s` of a sensor whose image
/// is `w × h` px of `mm` mm/px: its centroid in mm from the image's centre.
pub fn sensor_reading(s: &ContactSummary, (w, h, mm): (f64, f64, f64)) -> SensorReading {
    SensorReading {
        in_contact: s.in_contact,
        area_mm2: s.area_mm2,
        max_depth_mm: s.max_depth_mm.unwrap_or(0.0),
        volume_mm3: s.volume_mm3.unwrap_or(0.0),
        force_n: s.force_n.unwrap_or(0.0),
        centroid_mm: s
            .centroid_px
            .map(|(x, y)| ((x - w / 2.0) * mm, (y - h / 2.0) * mm)),
        slip: s.shear.map(|e| e.slip()),
    }
}

impl Sensing for Tactile {
    fn process(&mut self, set: &FrameSet) -> Vec<Option<SensorReading>> {
        Tactile::process(self, set)
    }

    fn frame_arrived(&mut self, frame: &ReceivedFrame) {
        Tactile::frame_arrived(self, frame);
    }

    fn reference_sets_missing(&self) -> usize {
        Tactile::reference_sets_missing(self)
    }

    fn offer_reference(&mut self, set: &FrameSet) {
        Tactile::offer_reference(self, set);
    }
}

impl DepthWindows for Tactile {
    fn depth_window(&self, index: usize) -> Option<DepthWindow> {
        Tactile::depth_window(self, index)
    }
}
