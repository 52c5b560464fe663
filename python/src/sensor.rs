//! One sensor's pipeline from Python: `Model` (a gradient model file), `Sensor` (the
//! pipeline `gelgrip reconstruct` runs, set up once for a model, a background and options)
//! with `process` and `process_many`, its `Reconstruction`, and `poisson`.
//!
//! `Sensor.process` is a pure function of the model, the background, the options, the
//! noise frames and the frame: the pipeline's reference is the background and stays so
//! (no drift), and its noise thresholds are measured once, at construction. Pipelines are
//! kept in a pool so that calls from several threads (and `process_many`'s parallel
//! frames) each get one without setting it up again; the GIL is released while they run.

use std::path::PathBuf;
use std::sync::Mutex;

use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;

use gelgrip_plugins::gradient::{GradientModel, MlpMode};
use gelgrip_plugins::halves::keep_a_worker_awake;
use gelgrip_plugins::image::RgbImage;
use gelgrip_plugins::poisson::{PoissonPlan, Solver};
use gelgrip_plugins::reconstruct::{
    Reconstruction as RustReconstruction, Reconstructor, quiet_sample_indices,
};

use crate::arrays::{self, ColorOrder, FrameIn};
use crate::errors;

/// A gradient model: a LUT or an MLP, as `calibrate train`, `transfer` or `bake` wrote it.
#[pyclass(frozen, module = "gelgrip")]
#[derive(Debug, Clone)]
pub struct Model {
    pub(crate) inner: GradientModel,
    /// `calibrate train --json`, for a model `train` returned.
    report: Option<String>,
}

impl Model {
    /// A model `train` returned, with its report (JSON).
    pub(crate) fn trained(inner: GradientModel, report: String) -> Self {
        Self {
            inner,
            report: Some(report),
        }
    }

    /// The model as `mode` runs it (an MLP; a LUT is the same either way).
    pub(crate) fn in_mode(&self, mode: MlpMode) -> GradientModel {
        match &self.inner {
            GradientModel::Mlp { model, net, .. } => GradientModel::Mlp {
                model: model.clone(),
                net: net.clone(),
                mode,
            },
            lut => lut.clone(),
        }
    }
}

#[pymethods]
impl Model {
    /// Load a model file (`FileNotFoundError` when it is missing, `ModelError` when it is
    /// not a usable model).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        errors::require_file(&path, "model")?;
        let inner = py
            .detach(|| GradientModel::load(&path, MlpMode::ContactOnly))
            .map_err(|e| {
                errors::ModelError::new_err(format!(
                    "{}: not a usable model file: {e}",
                    path.display()
                ))
            })?;
        Ok(Self {
            inner,
            report: None,
        })
    }

    /// For a model `train` returned: its `calibrate train --json` report (a dict); None
    /// for a model loaded from a file.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.report
            .as_ref()
            .map(|text| py.import("json")?.call_method1("loads", (text,)))
            .transpose()
    }

    /// Write the model file (`.safetensors`).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let result = py.detach(|| match &self.inner {
            GradientModel::Lut(lut) => lut.save(&path),
            GradientModel::Mlp { model, .. } => model.save(&path),
        });
        result.map_err(|e| errors::ModelError::new_err(e.to_string()))
    }

    /// `lut`, `baked-mlp`, `mlp-dense` or `mlp-contact`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.name()
    }

    /// The key the model reads: `diff`, `relative` or `raw`.
    #[getter]
    fn input(&self) -> &'static str {
        self.inner.input().as_str()
    }

    /// The image size it was trained at, `(width, height)`, px.
    #[getter]
    fn size(&self) -> (usize, usize) {
        self.inner.size()
    }

    /// The pixel size it was trained at, mm (None for files written before it was
    /// recorded).
    #[getter]
    fn mm_per_px(&self) -> Option<f64> {
        self.inner.mm_per_px()
    }

    fn __repr__(&self) -> String {
        let (w, h) = self.inner.size();
        format!(
            "Model(kind={:?}, input={:?}, size=({w}, {h}), mm_per_px={:?})",
            self.inner.name(),
            self.inner.input().as_str(),
            self.inner.mm_per_px()
        )
    }
}

/// What a sensor's pipelines are set up from.
#[derive(Debug)]
struct Setup {
    model: GradientModel,
    background: RgbImage,
    noise_frames: Vec<RgbImage>,
    mm_per_px: f64,
    solver: Solver,
}

impl Setup {
    fn pipeline(&self) -> Result<Reconstructor, gelgrip_plugins::reconstruct::ReconstructError> {
        let samples: Vec<&RgbImage> = self.noise_frames.iter().collect();
        Reconstructor::new(
            self.model.clone(),
            &self.background,
            &samples,
            self.mm_per_px,
            self.solver,
        )
    }
}

/// A solver by name.
pub(crate) fn solver(name: &str) -> PyResult<Solver> {
    Solver::parse(name).ok_or_else(|| {
        PyValueError::new_err(format!("solver={name:?}: expected \"dct\" or \"dst\""))
    })
}

/// One sensor's pipeline, as `gelgrip reconstruct` runs it.
#[pyclass(frozen, module = "gelgrip")]
pub struct Sensor {
    setup: Setup,
    order: ColorOrder,
    /// Pipelines not in use (one per concurrent call at most).
    pool: Mutex<Vec<Reconstructor>>,
}

/// One frame's reconstruction, in Rust, before it is handed to Python.
type Outcome = Result<RustReconstruction, PyErr>;

impl Sensor {
    /// Reconstruct `frame` (GIL released by the caller) on a pipeline from the pool.
    fn run(&self, frame: FrameIn, name: &str) -> Outcome {
        let image = frame.into_image(name).map_err(|e| errors::image(&e))?;
        let pipe = self.pool.lock().ok().and_then(|mut p| p.pop());
        let mut pipe = match pipe {
            Some(p) => p,
            None => self.setup.pipeline().map_err(|e| errors::reconstruct(&e))?,
        };
        let result = pipe
            .reconstruct(&image)
            .map_err(|e| errors::reconstruct(&e));
        if let Ok(mut pool) = self.pool.lock() {
            pool.push(pipe);
        }
        result
    }
}

#[pymethods]
impl Sensor {
    /// The pipeline for `model` with `background` (H×W×3 uint8 in `color_order`, the
    /// model's size); `mm_per_px` None takes the model's; `noise_frames` (frames like the
    /// ones to come: their untouched parts measure the camera's noise, as `gelgrip
    /// reconstruct` does with its images; up to 16 evenly spaced are used) None measures
    /// it on the background alone, so every difference from it counts.
    #[new]
    #[pyo3(signature = (model, background, mm_per_px=None, solver="dct", color_order="rgb", noise_frames=None))]
    fn new(
        py: Python<'_>,
        model: &Model,
        background: &Bound<'_, PyAny>,
        mm_per_px: Option<f64>,
        solver: &str,
        color_order: &str,
        noise_frames: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let order = ColorOrder::parse(color_order)?;
        let solver = self::solver(solver)?;
        let background = arrays::image_in(background, order, "background")?;
        let mm_per_px = match (mm_per_px, model.inner.mm_per_px()) {
            (Some(s), _) | (None, Some(s)) => s,
            (None, None) => {
                return Err(PyValueError::new_err(
                    "mm_per_px: the model file does not record the pixel size it was trained \
                     at: pass mm_per_px (mm per pixel on the gel)",
                ));
            }
        };
        let frames = match noise_frames {
            Some(obj) => arrays::frames_in(obj, order)?,
            None => Vec::new(),
        };
        let noise_frames = py.detach(|| decode_samples(frames))?;
        let setup = Setup {
            model: model.in_mode(MlpMode::ContactOnly),
            background,
            noise_frames,
            mm_per_px,
            solver,
        };
        let first = py
            .detach(|| setup.pipeline())
            .map_err(|e| errors::reconstruct(&e))?;
        Ok(Self {
            setup,
            order,
            pool: Mutex::new(vec![first]),
        })
    }

    /// Reconstruct one frame: an H×W×3 uint8 array (any strides, in the sensor's colour
    /// order) of the background's size, or JPEG bytes.
    fn process(&self, py: Python<'_>, frame: &Bound<'_, PyAny>) -> PyResult<Reconstruction> {
        let frame = arrays::frame_in(frame, self.order, "frame")?;
        let r = py.detach(|| {
            // One frame on two cores: a pool worker polls while this thread works, and
            // takes half of each large stage (bit for bit one thread's result).
            let _awake = keep_a_worker_awake();
            self.run(frame, "frame")
        })?;
        Reconstruction::new(py, r)
    }

    /// Reconstruct many frames in parallel: an N×H×W×3 uint8 array or a list of frames.
    /// The first frame that fails raises, naming its index.
    fn process_many(
        &self,
        py: Python<'_>,
        frames: &Bound<'_, PyAny>,
    ) -> PyResult<Vec<Reconstruction>> {
        let frames = arrays::frames_in(frames, self.order)?;
        let outcomes: Vec<Outcome> = py.detach(|| {
            frames
                .into_par_iter()
                .enumerate()
                .map(|(i, f)| self.run(f, &format!("frames[{i}]")))
                .collect()
        });
        outcomes
            .into_iter()
            .enumerate()
            .map(|(i, r)| {
                let r = r.map_err(|e| {
                    let msg = format!("frames[{i}]: {}", e.value(py));
                    PyErr::from_type(e.get_type(py), msg)
                })?;
                Reconstruction::new(py, r)
            })
            .collect()
    }

    /// The pixel size in use, mm.
    #[getter]
    fn mm_per_px(&self) -> f64 {
        self.setup.mm_per_px
    }

    /// The frame size, `(width, height)`, px.
    #[getter]
    fn size(&self) -> (usize, usize) {
        (self.setup.background.width, self.setup.background.height)
    }

    fn __repr__(&self) -> String {
        format!(
            "Sensor(size=({}, {}), mm_per_px={}, solver={:?}, model={:?})",
            self.setup.background.width,
            self.setup.background.height,
            self.setup.mm_per_px,
            self.setup.solver.as_str(),
            self.setup.model.name()
        )
    }
}

/// The noise frames, decoded; the ones used are evenly spaced, as `gelgrip reconstruct`
/// picks them from its images.
fn decode_samples(frames: Vec<FrameIn>) -> PyResult<Vec<RgbImage>> {
    let n = frames.len();
    let mut frames: Vec<Option<FrameIn>> = frames.into_iter().map(Some).collect();
    quiet_sample_indices(n)
        .into_iter()
        .filter_map(|k| frames[k].take().map(|f| (k, f)))
        .map(|(k, f)| {
            f.into_image(&format!("noise_frames[{k}]"))
                .map_err(|e| errors::image(&e))
        })
        .collect()
}

/// One frame reconstructed: depth, gradients and contact over the whole frame, and the
/// contact's figures as `gelgrip reconstruct --json` reports them.
#[pyclass(frozen, module = "gelgrip")]
pub struct Reconstruction {
    /// H×W float32, mm, positive into the gel, zero outside the solved window.
    #[pyo3(get)]
    depth_mm: Py<PyArrayDyn<f32>>,
    /// H×W×2 float32 `(gx, gy)`, px per px, zero outside the window.
    #[pyo3(get)]
    gradients: Py<PyArrayDyn<f32>>,
    /// H×W bool: pixels deeper than the noise threshold.
    #[pyo3(get)]
    contact: Py<PyArrayDyn<bool>>,
    /// Anything in contact.
    #[pyo3(get)]
    in_contact: bool,
    /// Contact area, mm².
    #[pyo3(get)]
    area_mm2: f64,
    /// Deepest point, mm.
    #[pyo3(get)]
    max_depth_mm: f64,
    /// Indentation volume, mm³.
    #[pyo3(get)]
    volume_mm3: f64,
    /// Contact centroid `(x, y)`, px; None without contact.
    #[pyo3(get)]
    centroid_px: Option<(f64, f64)>,
}

impl Reconstruction {
    fn new(py: Python<'_>, r: RustReconstruction) -> PyResult<Self> {
        let f = r.figures();
        let (w, h) = (r.width, r.height);
        Ok(Self {
            depth_mm: arrays::readonly(py, r.depth_mm, &[h, w])?.unbind(),
            gradients: arrays::readonly(py, r.gradients, &[h, w, 2])?.unbind(),
            contact: arrays::readonly(py, r.contact, &[h, w])?.unbind(),
            in_contact: f.in_contact,
            area_mm2: f.area_mm2,
            max_depth_mm: f.max_depth_mm,
            volume_mm3: f.volume_mm3,
            centroid_px: f.centroid_px.map(|[x, y]| (x, y)),
        })
    }
}

#[pymethods]
impl Reconstruction {
    fn __repr__(&self) -> String {
        format!(
            "Reconstruction(in_contact={}, area_mm2={:.3}, max_depth_mm={:.4}, volume_mm3={:.4}, centroid_px={:?})",
            self.in_contact, self.area_mm2, self.max_depth_mm, self.volume_mm3, self.centroid_px
        )
    }
}

/// Integrate an H×W×2 gradient array (float32 or float64; channel 0 gx, 1 gy, px per px)
/// into H×W depth (float32, px), as `gelgrip depth` does: solved in float64, `dst` (zero
/// border, its default) or `dct` (zero mean).
#[pyfunction]
#[pyo3(signature = (gradients, solver="dst"))]
pub fn poisson<'py>(
    py: Python<'py>,
    gradients: &Bound<'py, PyAny>,
    solver: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let solver = self::solver(solver)?;
    let (gx, gy, h, w) = gradients_in(gradients)?;
    let z = py.detach(|| {
        let mut z = vec![0.0f64; h * w];
        PoissonPlan::new(solver, h, w).solve(&gx, &gy, &mut z);
        z.iter().map(|v| *v as f32).collect::<Vec<f32>>()
    });
    arrays::readonly(py, z, &[h, w])
}

/// `(gx, gy, h, w)` of an H×W×2 float array of any strides.
fn gradients_in(obj: &Bound<'_, PyAny>) -> PyResult<(Vec<f64>, Vec<f64>, usize, usize)> {
    let Ok(untyped) = obj.cast::<PyUntypedArray>() else {
        return Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "gradients: expected a numpy array (H×W×2 float32 or float64), got {}",
            obj.get_type().name()?
        )));
    };
    let shape = untyped.shape().to_vec();
    if shape.len() != 3 || shape[2] != 2 || shape[0] < 3 || shape[1] < 3 {
        return Err(PyValueError::new_err(format!(
            "gradients: expected shape (H, W, 2) with H, W >= 3, got {shape:?}"
        )));
    }
    let values: Vec<f64> = if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        let a = a
            .try_readonly()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        a.as_array().iter().map(|v| f64::from(*v)).collect()
    } else if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        let a = a
            .try_readonly()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        a.as_array().iter().copied().collect()
    } else {
        return Err(PyValueError::new_err(format!(
            "gradients: expected dtype float32 or float64, got {}",
            untyped.dtype()
        )));
    };
    let gx = values.iter().step_by(2).copied().collect();
    let gy = values.iter().skip(1).step_by(2).copied().collect();
    Ok((gx, gy, shape[0], shape[1]))
}
