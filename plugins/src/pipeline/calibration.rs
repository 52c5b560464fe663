//! Calibrating a [`SensorPipeline`] on no-contact frames: its reference (their mean, or a
//! given background) and the noise thresholds measured on the same frames.

use super::{Frame, PIXEL_NOISE_PERCENTILE, PipelineError, SensorPipeline, pixel_difference};
use crate::contact::{MIN_CONTACT_PX, NoiseModel};
use crate::markers::InkFill;

impl SensorPipeline {
    /// Capture the reference from no-contact frames (their mean), then measure the noise
    /// thresholds on the same frames.
    pub fn calibrate(&mut self, no_contact: &[&[u8]]) -> Result<(), PipelineError> {
        let frames: Vec<Frame<'_>> = no_contact.iter().map(|j| Frame::Jpeg(j)).collect();
        self.calibrate_frames(None, &frames)
    }

    /// [`SensorPipeline::calibrate`] from decoded frames (RGB8, `width × height` of
    /// [`SensorPipeline::size`]), as `calibrate eval` feeds a press dataset's images.
    pub fn calibrate_rgb(&mut self, no_contact: &[&[u8]]) -> Result<(), PipelineError> {
        let frames: Vec<Frame<'_>> = no_contact.iter().map(|f| Frame::Rgb(f)).collect();
        self.calibrate_frames(None, &frames)
    }

    /// [`SensorPipeline::calibrate_rgb`] with `reference` (RGB8, decoded) as the reference
    /// instead of the frames' mean: the noise thresholds are measured on `no_contact`
    /// against it (`gelgrip reconstruct`, whose user gives the background).
    pub fn calibrate_rgb_against(
        &mut self,
        reference: &[u8],
        no_contact: &[&[u8]],
    ) -> Result<(), PipelineError> {
        let frames: Vec<Frame<'_>> = no_contact.iter().map(|f| Frame::Rgb(f)).collect();
        self.calibrate_frames(Some(Frame::Rgb(reference)), &frames)
    }

    /// The mean of `frames` as loaded (`blurred`: through the model's blur, as every
    /// frame is read; else sharp, as the dots are found).
    fn mean_of(&mut self, frames: &[Frame<'_>], blurred: bool) -> Result<Vec<f32>, PipelineError> {
        let mut sum = vec![0.0f32; self.rgb.len()];
        for frame in frames {
            if blurred {
                self.load(*frame)?;
            } else {
                self.load_unblurred(*frame)?;
            }
            sum.iter_mut()
                .zip(&self.rgb)
                .for_each(|(s, v)| *s += f32::from(*v));
        }
        let n = frames.len().max(1) as f32;
        sum.iter_mut().for_each(|s| *s /= n);
        Ok(sum)
    }

    /// Whether the reference showed a marker gel's dots (they are filled in every frame),
    /// and how many.
    pub fn marker_dots(&self) -> Option<usize> {
        self.ink.as_ref().map(InkFill::dots)
    }

    /// A marker gel's dots as the pipeline finds, follows and fills them (`None`: a plain
    /// gel), so that their stages can be timed apart (`bench pipeline --markers`).
    pub fn ink_fill(&self) -> Option<&InkFill> {
        self.ink.as_ref()
    }

    /// The reference (`reference`, else the mean of `no_contact`), then the noise thresholds
    /// measured on `no_contact`.
    fn calibrate_frames(
        &mut self,
        reference: Option<Frame<'_>>,
        no_contact: &[Frame<'_>],
    ) -> Result<(), PipelineError> {
        let averaged = if reference.is_some() {
            reference.as_slice()
        } else {
            no_contact
        };
        // A marker gel's dots are found on the reference as decoded (sharp: the model's
        // blur, chosen for noisy frames, would smear them into the gel), then the
        // reference is loaded again with them filled, through the blur (as every frame
        // will be).
        self.ink = None;
        let sharp = self.mean_of(averaged, false)?;
        self.ink = InkFill::detect(&sharp, self.width, self.height);
        let sum = self.mean_of(averaged, true)?;
        self.reference = Some(sum);
        self.reference_changed();
        self.predict_background()?;
        let mut pixel_activity = Vec::new();
        let (mut activity, mut depth) = (Vec::new(), Vec::new());
        let mut deepest_mm = 0.0f32;
        let windows = self.noise_windows();
        for frame in no_contact {
            self.load(*frame)?;
            if let Some(ink) = &mut self.ink {
                ink.learn_noise();
            }
            if let Some(reference) = &self.reference {
                pixel_activity.extend(
                    self.rgb
                        .chunks_exact(3)
                        .zip(reference.chunks_exact(3))
                        .map(|(p, r)| pixel_difference(p, r)),
                );
            }
            self.block_activity();
            self.mark_near_active(None);
            activity.extend_from_slice(&self.blocks);
            if self.choice.stages.solver.is_some() {
                deepest_mm = deepest_mm.max(self.noise_depths_mm(&windows, &mut depth)?);
            }
        }
        self.pixel_threshold = if pixel_activity.is_empty() {
            0.0
        } else {
            let k =
                (pixel_activity.len() * PIXEL_NOISE_PERCENTILE / 100).min(pixel_activity.len() - 1);
            *pixel_activity.select_nth_unstable_by(k, f32::total_cmp).1
        };
        self.noise = Some(NoiseModel::measure(&activity, &depth, deepest_mm));
        Ok(())
    }

    /// The loaded no-contact frame's |depth| (mm) over each of `windows`, appended to
    /// `depth_mm`; returns the deepest that [`MIN_CONTACT_PX`] pixels of one window reached
    /// (into the gel): the least threshold under which this frame would read no contact.
    fn noise_depths_mm(
        &mut self,
        windows: &[(usize, usize, usize, usize)],
        depth_mm: &mut Vec<f32>,
    ) -> Result<f32, PipelineError> {
        let mm = self.mm_per_px as f32;
        let mut deepest_mm = 0.0f32;
        let mut into_gel = Vec::new();
        for window in windows {
            into_gel.clear();
            for v in self.solve_window(*window, true)? {
                depth_mm.push((v * mm).abs());
                into_gel.push(v * mm);
            }
            if into_gel.len() >= MIN_CONTACT_PX {
                let k = MIN_CONTACT_PX - 1;
                let (_, kth, _) = into_gel.select_nth_unstable_by(k, |a, b| b.total_cmp(a));
                if kth.is_finite() {
                    deepest_mm = deepest_mm.max(*kth);
                }
            }
        }
        Ok(deepest_mm)
    }
}
