//! NumPy `.npy` files: read `<f4` or `<f8` in C order (a named error otherwise), write `<f4`.
//! Gradients are H×W×2 with channel 0 = Gx and channel 1 = Gy (CONTRACTS.md).

use std::io::{BufReader, BufWriter};
use std::path::Path;

use npyz::WriterBuilder;
use thiserror::Error;

/// A `.npy` file could not be used.
#[derive(Debug, Error)]
pub enum NpyError {
    /// File system or format error.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A dtype other than `<f4` / `<f8`.
    #[error("{path}: dtype {actual}, expected <f4 or <f8")]
    DType {
        /// The file.
        path: String,
        /// The dtype found.
        actual: String,
    },
    /// Fortran order.
    #[error("{path}: Fortran-ordered array, expected C order")]
    Order {
        /// The file.
        path: String,
    },
    /// A shape the command cannot use.
    #[error("{path}: shape {actual:?}, expected {expected}")]
    Shape {
        /// The file.
        path: String,
        /// The shape found.
        actual: Vec<u64>,
        /// What is needed.
        expected: String,
    },
}

/// Largest array read (2 × 8192 × 8192: far beyond any tactile image), so a corrupt header
/// cannot make the reader allocate without bound.
pub const MAX_ELEMENTS: u64 = 2 * 8192 * 8192;

/// An array of f64 values with its shape.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Dimensions.
    pub shape: Vec<usize>,
    /// Values in C order.
    pub data: Vec<f64>,
}

/// Read `path`.
pub fn read(path: &Path) -> Result<NpyArray, NpyError> {
    let p = path.display().to_string();
    let io = |source| NpyError::Io {
        path: p.clone(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let npy = npyz::NpyFile::new(BufReader::new(file)).map_err(io)?;
    if npy.order() != npyz::Order::C {
        return Err(NpyError::Order { path: p });
    }
    let shape: Vec<usize> = npy.shape().iter().map(|d| *d as usize).collect();
    let elements = npy.shape().iter().try_fold(1u64, |n, d| n.checked_mul(*d));
    if elements.is_none_or(|n| n > MAX_ELEMENTS) {
        return Err(NpyError::Shape {
            path: p,
            actual: npy.shape().to_vec(),
            expected: format!("at most {MAX_ELEMENTS} elements"),
        });
    }
    let descr = match npy.dtype() {
        npyz::DType::Plain(ts) => ts.to_string(),
        other => other.descr(),
    };
    let data = match descr.as_str() {
        "<f8" => npy.into_vec::<f64>().map_err(io)?,
        "<f4" => npy
            .into_vec::<f32>()
            .map_err(io)?
            .into_iter()
            .map(f64::from)
            .collect(),
        other => {
            return Err(NpyError::DType {
                path: p,
                actual: other.to_string(),
            });
        }
    };
    Ok(NpyArray { shape, data })
}

/// Write `data` with `shape` as `<f4`.
pub fn write_f32(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), NpyError> {
    let p = path.display().to_string();
    let io = |source| NpyError::Io {
        path: p.clone(),
        source,
    };
    let file = std::fs::File::create(path).map_err(io)?;
    let dims: Vec<u64> = shape.iter().map(|d| *d as u64).collect();
    let mut writer = npyz::WriteOptions::new()
        .default_dtype()
        .shape(&dims)
        .writer(BufWriter::new(file))
        .begin_nd()
        .map_err(io)?;
    writer.extend(data.iter().copied()).map_err(io)?;
    writer.finish().map_err(io)
}

/// Split an H×W×2 gradient array into (gx, gy, H, W).
pub fn split_gradients(
    path: &Path,
    a: &NpyArray,
) -> Result<(Vec<f64>, Vec<f64>, usize, usize), NpyError> {
    match a.shape.as_slice() {
        [h, w, 2] if *h > 0 && *w > 0 => {
            let gx = a.data.iter().step_by(2).copied().collect();
            let gy = a.data.iter().skip(1).step_by(2).copied().collect();
            Ok((gx, gy, *h, *w))
        }
        _ => Err(NpyError::Shape {
            path: path.display().to_string(),
            actual: a.shape.iter().map(|d| *d as u64).collect(),
            expected: "H x W x 2 (channel 0 = Gx, 1 = Gy)".into(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_rejects_bad_shapes() {
        let dir = std::env::temp_dir().join(format!("gelgrip-npy-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("g.npy");
        let data: Vec<f32> = (0..24).map(|i| i as f32 * 0.5).collect();
        write_f32(&path, &[3, 4, 2], &data).expect("write");
        let a = read(&path).expect("read");
        assert_eq!(a.shape, vec![3, 4, 2]);
        let (gx, gy, h, w) = split_gradients(&path, &a).expect("split");
        assert_eq!((h, w), (3, 4));
        assert_eq!(gx[1], 1.0);
        assert_eq!(gy[0], 0.5);
        write_f32(&path, &[24], &data).expect("write");
        let err = split_gradients(&path, &read(&path).expect("read")).expect_err("1-D");
        assert!(err.to_string().contains("H x W x 2"), "{err}");
        std::fs::write(&path, b"\x93NUMPY garbage").expect("write");
        assert!(read(&path).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
