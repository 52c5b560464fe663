//! The gradient-model file: one `.safetensors` file whose `__metadata__` holds `format` =
//! `gelgrip-gradient-model`, `version`, `kind` (`lut`|`mlp`), `input` (`diff`|`raw`),
//! `width`, `height` and `offset_rgb` (CONTRACTS.md, "Model file"), and optionally
//! `mm_per_px`, the pixel size on the gel the model was trained at (files written before
//! it have none: [`mm_per_px`]).

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
