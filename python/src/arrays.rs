//! numpy in and out. Frames and backgrounds come in as H×W×3 `uint8` arrays of any strides
//! (copied, in the caller's colour order, into the RGB buffer the pipeline reads) or as JPEG
//! bytes; results go out as read-only numpy arrays that own the result's Rust buffers (no
//! copy once the result is built). Anything else is a `ValueError` or `TypeError` that
//! names what was expected.

use numpy::ndarray::{ArrayD, ArrayViewD, IxDyn};
use numpy::{
    Element, IntoPyArray, PyArrayDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};

use gelgrip_plugins::image::RgbImage;

/// The channel order of the arrays a caller gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorOrder {
    /// Red, green, blue (the pipeline's own).
    Rgb,
    /// Blue, green, red (OpenCV's).
    Bgr,
}

impl ColorOrder {
    /// `"rgb"` or `"bgr"`.
    pub fn parse(s: &str) -> PyResult<Self> {
        match s {
            "rgb" => Ok(Self::Rgb),
            "bgr" => Ok(Self::Bgr),
            _ => Err(PyValueError::new_err(format!(
                "color_order={s:?}: expected \"rgb\" or \"bgr\""
            ))),
        }
    }
}

/// A frame taken from Python: decoded pixels (RGB), or JPEG bytes to decode.
#[derive(Debug, Clone)]
pub enum FrameIn {
    /// RGB8, row-major.
    Rgb(RgbImage),
    /// A JPEG file's bytes.
    Jpeg(Vec<u8>),
}

impl FrameIn {
    /// The pixels, decoding a JPEG (named `name` in errors).
    pub fn into_image(self, name: &str) -> Result<RgbImage, gelgrip_plugins::image::ImageError> {
        match self {
            FrameIn::Rgb(img) => Ok(img),
            FrameIn::Jpeg(bytes) => RgbImage::from_jpeg(name, &bytes),
        }
    }
}

/// `obj` as a frame: JPEG `bytes` (or a `bytearray`/`memoryview` of them), or an H×W×3
/// `uint8` array of any strides in `order`. `what` names it in errors.
pub fn frame_in(obj: &Bound<'_, PyAny>, order: ColorOrder, what: &str) -> PyResult<FrameIn> {
    if let Ok(bytes) = obj.cast::<PyBytes>() {
        return Ok(FrameIn::Jpeg(bytes.as_bytes().to_vec()));
    }
    if obj.is_instance_of::<pyo3::types::PyByteArray>()
        || obj.is_instance_of::<pyo3::types::PyMemoryView>()
    {
        let copy = obj.py().get_type::<PyBytes>().call1((obj,))?;
        let bytes = copy.cast::<PyBytes>()?.as_bytes().to_vec();
        return Ok(FrameIn::Jpeg(bytes));
    }
    image_in(obj, order, what).map(FrameIn::Rgb)
}

/// `obj` as an H×W×3 `uint8` array of any strides in `order`, copied into RGB8.
pub fn image_in(obj: &Bound<'_, PyAny>, order: ColorOrder, what: &str) -> PyResult<RgbImage> {
    let Ok(untyped) = obj.cast::<PyUntypedArray>() else {
        return Err(PyTypeError::new_err(format!(
            "{what}: expected a numpy array (H×W×3 uint8) or JPEG bytes, got {}",
            obj.get_type().name()?
        )));
    };
    let shape = untyped.shape().to_vec();
    let Ok(array) = obj.cast::<PyArrayDyn<u8>>() else {
        return Err(PyValueError::new_err(format!(
            "{what}: expected dtype uint8, got {} (shape {shape:?})",
            untyped.dtype()
        )));
    };
    if shape.len() != 3 || shape[2] != 3 || shape[0] == 0 || shape[1] == 0 {
        return Err(PyValueError::new_err(format!(
            "{what}: expected shape (H, W, 3), got {shape:?}"
        )));
    }
    let readonly = array
        .try_readonly()
        .map_err(|e| PyValueError::new_err(format!("{what}: the array cannot be read now: {e}")))?;
    let data = rgb_bytes(readonly.as_array(), order);
    Ok(RgbImage {
        width: shape[1],
        height: shape[0],
        data,
    })
}

/// The pixels of an H×W×3 view in row-major RGB order.
fn rgb_bytes(view: ArrayViewD<'_, u8>, order: ColorOrder) -> Vec<u8> {
    let mut data = match view.as_slice() {
        Some(contiguous) => contiguous.to_vec(),
        None => view.iter().copied().collect(),
    };
    if order == ColorOrder::Bgr {
        data.chunks_exact_mut(3).for_each(|p| p.swap(0, 2));
    }
    data
}

/// A read-only numpy array of `shape` that owns `data` (moved, not copied).
pub fn readonly<'py, T: Element>(
    py: Python<'py>,
    data: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let array = ArrayD::from_shape_vec(IxDyn(shape), data)
        .map_err(|e| PyValueError::new_err(format!("array of shape {shape:?}: {e}")))?;
    let array = array.into_pyarray(py);
    let flags = PyDict::new(py);
    flags.set_item("write", false)?;
    array.call_method("setflags", (), Some(&flags))?;
    Ok(array)
}

/// The frames of `obj`: an N×H×W×3 `uint8` array, or a sequence of frames (arrays or JPEG
/// bytes, as [`frame_in`]).
pub fn frames_in(obj: &Bound<'_, PyAny>, order: ColorOrder) -> PyResult<Vec<FrameIn>> {
    if let Ok(untyped) = obj.cast::<PyUntypedArray>() {
        let shape = untyped.shape();
        if shape.len() != 4 {
            return Err(PyValueError::new_err(format!(
                "frames: expected an array of shape (N, H, W, 3) or a list of frames, got shape {shape:?}"
            )));
        }
        let n = shape[0];
        return (0..n)
            .map(|i| frame_in(&obj.get_item(i)?, order, &format!("frames[{i}]")))
            .collect();
    }
    if obj.is_instance_of::<PyBytes>() {
        return Err(PyTypeError::new_err(
            "frames: expected an (N, H, W, 3) array or a list of frames, got one bytes object \
             (use process for one JPEG)",
        ));
    }
    let mut out = Vec::new();
    for (i, item) in obj.try_iter()?.enumerate() {
        out.push(frame_in(&item?, order, &format!("frames[{i}]"))?);
    }
    Ok(out)
}
