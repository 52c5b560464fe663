//! The gradient-model file: one `.safetensors` file whose `__metadata__` holds `format` =
//! `gelgrip-gradient-model`, `version`, `kind` (`lut`|`mlp`), `input` (`diff`|`raw`),
//! `width`, `height` and `offset_rgb` (CONTRACTS.md, "Model file"), and optionally
//! `mm_per_px`, the pixel size on the gel the model was trained at (files written before
//! it have none: [`mm_per_px`]), and `slopes`, which slope a gradient at a pixel is
//! ([`Slopes`]; files written before it have forward differences).

use std::collections::HashMap;
use std::path::Path;

use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use thiserror::Error;

/// Value of the `format` key.
pub const FORMAT: &str = "gelgrip-gradient-model";
/// Model file version written.
pub const VERSION: &str = "1";

/// The metadata every model file carries (CONTRACTS.md), for a model of `kind` and `input`
/// trained at `width × height`, with its zero-shot `offset_rgb`.
pub fn base_metadata(
    kind: &str,
    input: &str,
    (width, height): (usize, usize),
    offset_rgb: [f32; 3],
) -> HashMap<String, String> {
    HashMap::from([
        ("format".to_string(), FORMAT.to_string()),
        ("version".to_string(), VERSION.to_string()),
        ("kind".to_string(), kind.to_string()),
        ("input".to_string(), input.to_string()),
        ("width".to_string(), width.to_string()),
        ("height".to_string(), height.to_string()),
        ("offset_rgb".to_string(), rgb_string(offset_rgb)),
    ])
}

/// Metadata key of the pixel size the model was trained at, mm (optional).
pub const MM_PER_PX_KEY: &str = "mm_per_px";

/// Add `mm_per_px` to `metadata` when it is known.
pub fn put_mm_per_px(metadata: &mut HashMap<String, String>, mm_per_px: Option<f64>) {
    if let Some(mm) = mm_per_px {
        metadata.insert(MM_PER_PX_KEY.to_string(), mm.to_string());
    }
}

/// The file's `mm_per_px`: `None` when absent (a file written before the key); a value that
/// is not a positive finite number is an error naming the key.
pub fn mm_per_px(file: &ModelFile, path: &str) -> Result<Option<f64>, ModelFileError> {
    let Some(v) = file.metadata.get(MM_PER_PX_KEY) else {
        return Ok(None);
    };
    v.trim()
        .parse::<f64>()
        .ok()
        .filter(|mm| mm.is_finite() && *mm > 0.0)
        .map(Some)
        .ok_or_else(|| ModelFileError::Metadata {
            path: path.to_string(),
            key: MM_PER_PX_KEY.to_string(),
            actual: Some(v.clone()),
            expected: "a positive number (mm per pixel)".into(),
        })
}

/// Which slope a model's gradient at a pixel is (metadata `slopes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Slopes {
    /// `forward`: the forward difference to the next pixel, as the solvers take gradients
    /// (CONTRACTS.md, "Tactile conventions"): models trained before 2026-11-29, whose files
    /// have no `slopes`, and models fitted to such gradients.
    #[default]
    Forward,
    /// `footprint`: the mean slope over the pixel's own footprint, what its colour shows
    /// (`PressTruth::gradients`, what `calibrate train` labels). The gradient stage turns
    /// them into forward differences ([`to_forward_differences`]) before anything else
    /// sees them.
    Footprint,
}

/// Metadata key of [`Slopes`].
pub const SLOPES_KEY: &str = "slopes";

impl Slopes {
    /// `forward` or `footprint`.
    pub fn as_str(self) -> &'static str {
        match self {
            Slopes::Forward => "forward",
            Slopes::Footprint => "footprint",
        }
    }
}

/// Add `slopes` to `metadata`.
pub fn put_slopes(metadata: &mut HashMap<String, String>, slopes: Slopes) {
    metadata.insert(SLOPES_KEY.to_string(), slopes.as_str().to_string());
}

/// The file's [`Slopes`]: `forward` when absent (a file written before the key); another
/// value is an error naming the key.
pub fn slopes(file: &ModelFile, path: &str) -> Result<Slopes, ModelFileError> {
    match file.metadata.get(SLOPES_KEY).map(|v| v.trim()) {
        None | Some("forward") => Ok(Slopes::Forward),
        Some("footprint") => Ok(Slopes::Footprint),
        Some(v) => Err(ModelFileError::Metadata {
            path: path.to_string(),
            key: SLOPES_KEY.to_string(),
            actual: Some(v.to_string()),
            expected: "forward or footprint".into(),
        }),
    }
}

/// Turn a `w`-wide row-major map of footprint slopes into the forward differences the
/// solvers take, in place: each gradient becomes the mean of its pixel's slope and the next
/// pixel's (right for `gx`, below for `gy`), the slope at the point between them; the last
/// column of `gx` and last row of `gy` keep their own. The sum along a row (column) is
/// kept but for half of its ends, so what closed still closes.
pub fn to_forward_differences<T>(gx: &mut [T], gy: &mut [T], w: usize)
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<Output = T> + From<f32>,
{
    let half = T::from(0.5);
    if w == 0 {
        return;
    }
    for row in gx.chunks_exact_mut(w) {
        for x in 0..w.saturating_sub(1) {
            row[x] = half * (row[x] + row[x + 1]);
        }
    }
    let n = gy.len();
    for p in 0..n.saturating_sub(w) {
        gy[p] = half * (gy[p] + gy[p + w]);
    }
}

/// Three numbers as metadata: `r,g,b`.
pub fn rgb_string(v: [f32; 3]) -> String {
    format!("{},{},{}", v[0], v[1], v[2])
}

/// Metadata `r,g,b`: three comma-separated finite numbers.
pub fn parse_rgb(s: Option<&str>) -> Option<[f32; 3]> {
    let v: Vec<f32> = s?
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .ok()?;
    (v.len() == 3 && v.iter().all(|x| x.is_finite())).then(|| [v[0], v[1], v[2]])
}

/// A model file could not be read or written.
#[derive(Debug, Error)]
pub enum ModelFileError {
    /// File system error.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// Not a safetensors file, or a tensor is missing or malformed.
    #[error("{path}: {detail}")]
    Format {
        /// The file.
        path: String,
        /// What is wrong.
        detail: String,
    },
    /// A metadata key is missing or has a value this build does not take.
    #[error("{path}: metadata `{key}` is {actual:?}, expected {expected}")]
    Metadata {
        /// The file.
        path: String,
        /// The key.
        key: String,
        /// What was found (`None` if absent).
        actual: Option<String>,
        /// What is allowed.
        expected: String,
    },
}

/// A model file's metadata and f32 tensors.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelFile {
    /// `__metadata__`.
    pub metadata: HashMap<String, String>,
    /// Tensors by name: shape and little-endian f32 values.
    pub tensors: Vec<(String, Vec<usize>, Vec<f32>)>,
}

impl ModelFile {
    /// Write to `path`.
    pub fn write(&self, path: &Path) -> Result<(), ModelFileError> {
        let p = path.display().to_string();
        let bytes: Vec<(String, Vec<usize>, Vec<u8>)> = self
            .tensors
            .iter()
            .map(|(n, s, v)| {
                (
                    n.clone(),
                    s.clone(),
                    v.iter().flat_map(|x| x.to_le_bytes()).collect(),
                )
            })
            .collect();
        let views = bytes
            .iter()
            .map(|(n, s, b)| TensorView::new(Dtype::F32, s.clone(), b).map(|v| (n.clone(), v)))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| ModelFileError::Format {
                path: p.clone(),
                detail: e.to_string(),
            })?;
        let out = safetensors::serialize(views, Some(self.metadata.clone())).map_err(|e| {
            ModelFileError::Format {
                path: p.clone(),
                detail: e.to_string(),
            }
        })?;
        std::fs::write(path, out).map_err(|source| ModelFileError::Io { path: p, source })
    }

    /// Read `path`, checking `format` and `version` (a file from a newer gelgrip, or one
    /// without metadata, is refused with the key and what was found).
    pub fn read(path: &Path) -> Result<Self, ModelFileError> {
        let p = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| ModelFileError::Io {
            path: p.clone(),
            source,
        })?;
        let fmt = |detail: String| ModelFileError::Format {
            path: p.clone(),
            detail,
        };
        let (_, meta) = SafeTensors::read_metadata(&bytes)
            .map_err(|e| fmt(format!("not a safetensors file: {e}")))?;
        let metadata = meta.metadata().clone().unwrap_or_default();
        let st = SafeTensors::deserialize(&bytes).map_err(|e| fmt(e.to_string()))?;
        let mut tensors = Vec::new();
        for name in st.names() {
            let t = st.tensor(name).map_err(|e| fmt(e.to_string()))?;
            if t.dtype() != Dtype::F32 {
                return Err(fmt(format!(
                    "tensor `{name}` is {:?}, expected F32",
                    t.dtype()
                )));
            }
            let values = t
                .data()
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            tensors.push((name.to_string(), t.shape().to_vec(), values));
        }
        let file = Self { metadata, tensors };
        file.expect_key(&p, "format", &[FORMAT])?;
        file.expect_key(&p, "version", &[VERSION])?;
        Ok(file)
    }

    /// The metadata value of `key`, which must be one of `allowed` (any value if empty).
    pub fn expect_key(
        &self,
        path: &str,
        key: &str,
        allowed: &[&str],
    ) -> Result<&str, ModelFileError> {
        let v = self.metadata.get(key).map(String::as_str);
        match v {
            Some(v) if allowed.is_empty() || allowed.contains(&v) => Ok(v),
            _ => Err(ModelFileError::Metadata {
                path: path.to_string(),
                key: key.to_string(),
                actual: v.map(str::to_string),
                expected: if allowed.is_empty() {
                    "a value".into()
                } else {
                    allowed.join(" | ")
                },
            }),
        }
    }

    /// The tensor `name`.
    pub fn tensor(&self, name: &str) -> Option<(&[usize], &[f32])> {
        self.tensors
            .iter()
            .find(|(n, _, _)| n == name)
            .map(|(_, s, v)| (s.as_slice(), v.as_slice()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Footprint slopes of a ramp z = x² along x (slope 2x at each centre) become its forward
    /// differences (2x + 1) inside; the last column keeps its own; gy likewise down columns.
    #[test]
    fn footprint_slopes_become_forward_differences() {
        let (w, h) = (5usize, 3usize);
        let mut gx: Vec<f64> = (0..w * h).map(|p| 2.0 * (p % w) as f64).collect();
        let mut gy: Vec<f64> = (0..w * h).map(|p| 2.0 * (p / w) as f64).collect();
        to_forward_differences(&mut gx, &mut gy, w);
        for p in 0..w * h {
            let (x, y) = ((p % w) as f64, (p / w) as f64);
            let want_x = if p % w + 1 < w {
                2.0 * x + 1.0
            } else {
                2.0 * x
            };
            let want_y = if p / w + 1 < h {
                2.0 * y + 1.0
            } else {
                2.0 * y
            };
            assert_eq!((gx[p], gy[p]), (want_x, want_y), "pixel {p}");
        }
        let (mut empty_x, mut empty_y) = (Vec::<f32>::new(), Vec::<f32>::new());
        to_forward_differences(&mut empty_x, &mut empty_y, 0);
    }

    #[test]
    fn slopes_default_to_forward_and_a_bad_value_names_the_key() {
        let mut file = ModelFile {
            metadata: HashMap::new(),
            tensors: Vec::new(),
        };
        assert_eq!(slopes(&file, "m").expect("absent"), Slopes::Forward);
        put_slopes(&mut file.metadata, Slopes::Footprint);
        assert_eq!(slopes(&file, "m").expect("written"), Slopes::Footprint);
        file.metadata.insert(SLOPES_KEY.into(), "centre".into());
        let err = slopes(&file, "m.safetensors").expect_err("bad");
        let text = err.to_string();
        assert!(text.contains("slopes") && text.contains("centre"), "{text}");
    }
}
