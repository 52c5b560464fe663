//! Image files read as gelgrip reads them (its own PNG and JPEG decoders), so that the
//! arrays a caller hands to `Sensor` are the pixels the CLI would see.

use std::path::PathBuf;

use numpy::PyArrayDyn;
use pyo3::prelude::*;

use gelgrip_plugins::image::RgbImage;

use crate::arrays::{self, ColorOrder};
use crate::errors;

/// A PNG or JPEG file (told apart by its first bytes) as an H×W×3 uint8 array in
/// `color_order`, read-only.
#[pyfunction]
#[pyo3(signature = (path, color_order="rgb"))]
pub fn read_image<'py>(
    py: Python<'py>,
    path: PathBuf,
    color_order: &str,
) -> PyResult<Bound<'py, PyArrayDyn<u8>>> {
    let order = ColorOrder::parse(color_order)?;
    errors::require_file(&path, "image")?;
    let image = py.detach(|| {
        let bytes =
            std::fs::read(&path).map_err(|source| gelgrip_plugins::image::ImageError::Io {
                path: path.display().to_string(),
                source,
            })?;
        if bytes.starts_with(&[0xFF, 0xD8]) {
            RgbImage::from_jpeg(&path.display().to_string(), &bytes)
        } else {
            RgbImage::read_png(&path)
        }
    });
    let mut image = image.map_err(|e| errors::image(&e))?;
    if order == ColorOrder::Bgr {
        image.data.chunks_exact_mut(3).for_each(|p| p.swap(0, 2));
    }
    arrays::readonly(py, image.data, &[image.height, image.width, 3])
}
