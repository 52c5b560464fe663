//! The gradient stage's model, whichever kind the model file holds: a LUT (trained, or an
//! MLP baked into one) or an MLP run densely or on the contact pixels only.

use std::path::Path;
use std::sync::Arc;

use crate::image::RgbImage;
use crate::lut::{Input, LutModel, relative_key};
use crate::mlp::{INPUTS, MlpError, MlpModel, MlpNet};
use crate::model_file::{ModelFile, Slopes, to_forward_differences};

/// How an MLP is evaluated in the pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MlpMode {
    /// Every pixel of the depth window.
    Dense,
    /// Only pixels whose difference from the reference exceeds the noise; every other pixel
    /// takes the background's cached prediction (zero gradient).
    ContactOnly,
}

impl MlpMode {
    /// `dense` or `contact`.
    pub fn as_str(self) -> &'static str {
        match self {
            MlpMode::Dense => "dense",
            MlpMode::ContactOnly => "contact",
        }
    }

    /// Parse `dense` or `contact`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "dense" => Some(MlpMode::Dense),
            "contact" => Some(MlpMode::ContactOnly),
            _ => None,
        }
    }
}

/// A loaded gradient model.
#[derive(Debug, Clone)]
pub enum GradientModel {
    /// Table lookup (trained, or a baked MLP).
    Lut(Arc<LutModel>),
    /// The network.
    Mlp {
        /// Its weights and transfer.
        model: Arc<MlpModel>,
        /// Its candle tensors.
        net: Arc<MlpNet>,
        /// Where it is evaluated.
        mode: MlpMode,
    },
}

impl GradientModel {
    /// A LUT model.
    pub fn lut(lut: LutModel) -> Self {
        GradientModel::Lut(Arc::new(lut))
    }

    /// An MLP model run in `mode`.
    pub fn mlp(model: MlpModel, mode: MlpMode) -> Result<Self, MlpError> {
        let net = model.net()?;
        Ok(GradientModel::Mlp {
            model: Arc::new(model),
            net: Arc::new(net),
            mode,
        })
    }

    /// Load a model file of either kind (`mode` applies to an MLP).
    pub fn load(path: &Path, mode: MlpMode) -> Result<Self, MlpError> {
        let p = path.display().to_string();
        let file = ModelFile::read(path)?;
        match file.expect_key(&p, "kind", &["lut", "mlp"])? {
            "lut" => Ok(Self::lut(LutModel::from_file(&file, &p)?)),
            _ => Self::mlp(MlpModel::from_file(&file, &p)?, mode),
        }
    }

    /// The key the model reads.
    pub fn input(&self) -> Input {
        match self {
            GradientModel::Lut(l) => l.input,
            GradientModel::Mlp { model, .. } => model.input,
        }
    }

    /// The image size `(width, height)` the model was trained at, px.
    pub fn size(&self) -> (usize, usize) {
        match self {
            GradientModel::Lut(l) => (l.width, l.height),
            GradientModel::Mlp { model, .. } => (model.width, model.height),
        }
    }

    /// Pixel size on the gel the model was trained at, mm (metadata `mm_per_px`; `None`
    /// for a file written before it was recorded).
    pub fn mm_per_px(&self) -> Option<f64> {
        match self {
            GradientModel::Lut(l) => l.mm_per_px,
            GradientModel::Mlp { model, .. } => model.mm_per_px,
        }
    }

    /// Which slope the model's raw output at a pixel is; [`GradientModel::predict_frame`]
    /// and the pipeline give forward differences whichever it is.
    pub fn slopes(&self) -> Slopes {
        match self {
            GradientModel::Lut(l) => l.slopes,
            GradientModel::Mlp { model, .. } => model.slopes,
        }
    }

    /// Box-blur radius the model reads frames through, px (0 for an MLP).
    pub fn blur_px(&self) -> usize {
        match self {
            GradientModel::Lut(l) => l.blur_px,
            GradientModel::Mlp { .. } => 0,
        }
    }

    /// A short name: `lut`, `baked-mlp`, `mlp-dense` or `mlp-contact`.
    pub fn name(&self) -> &'static str {
        match self {
            GradientModel::Lut(l) if l.source == "mlp" => "baked-mlp",
            GradientModel::Lut(_) => "lut",
            GradientModel::Mlp {
                mode: MlpMode::Dense,
                ..
            } => "mlp-dense",
            GradientModel::Mlp { .. } => "mlp-contact",
        }
    }

    /// Gradients of every pixel of `img` against the no-contact `background` (evaluation
    /// and calibration; the live pipeline works on windows), as forward differences
    /// (CONTRACTS.md), whichever [`Slopes`] the model learnt.
    pub fn predict_frame(
        &self,
        img: &RgbImage,
        background: &RgbImage,
        gx: &mut [f64],
        gy: &mut [f64],
    ) -> Result<(), MlpError> {
        let (w, h) = (img.width, img.height);
        let blurred;
        let (img, background) = match self.blur_px() {
            0 => (img, background),
            r => {
                blurred = (img.blurred(r), background.blurred(r));
                (&blurred.0, &blurred.1)
            }
        };
        let key = |p: usize| frame_key(img, background, p, self.input());
        match self {
            GradientModel::Lut(lut) => {
                for p in 0..w * h {
                    let [a, b] = lut.predict_at(key(p), p % w, p / w);
                    gx[p] = f64::from(a);
                    gy[p] = f64::from(b);
                }
            }
            GradientModel::Mlp { model, net, .. } => {
                let mut f = Vec::with_capacity(w * h * INPUTS);
                let mut fb = Vec::with_capacity(w * h * INPUTS);
                for p in 0..w * h {
                    let (x, y) = (p % w, p / w);
                    f.extend_from_slice(&model.features(key(p), x, y));
                    fb.extend_from_slice(&model.features(
                        background_key(background, p, model.input),
                        x,
                        y,
                    ));
                }
                let (out, bg) = (net.forward(&f)?, net.forward(&fb)?);
                for p in 0..w * h {
                    gx[p] = f64::from(out[2 * p] - bg[2 * p]);
                    gy[p] = f64::from(out[2 * p + 1] - bg[2 * p + 1]);
                }
            }
        }
        if self.slopes() == Slopes::Footprint {
            to_forward_differences(&mut gx[..w * h], &mut gy[..w * h], w);
        }
        Ok(())
    }
}

/// The key colour of pixel `p`: the difference from the background, or the raw colour.
pub fn frame_key(img: &RgbImage, background: &RgbImage, p: usize, input: Input) -> [f32; 3] {
    let v = |c: usize| f32::from(img.data[p * 3 + c]);
    match input {
        Input::Diff => [0, 1, 2].map(|c| v(c) - f32::from(background.data[p * 3 + c])),
        Input::Relative => {
            [0, 1, 2].map(|c| relative_key(v(c), f32::from(background.data[p * 3 + c])))
        }
        Input::Raw => [v(0), v(1), v(2)],
    }
}

/// The key a pixel has when nothing touches it: zero difference, or the background colour.
pub fn background_key(background: &RgbImage, p: usize, input: Input) -> [f32; 3] {
    match input {
        Input::Diff | Input::Relative => [0.0; 3],
        Input::Raw => [0, 1, 2].map(|c| f32::from(background.data[p * 3 + c])),
    }
}
