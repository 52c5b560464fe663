//! Gradient model `lut`: binned colour → mean (Gx, Gy), the classic GelSight baseline.
//!
//! The key is the difference colour (frame − reference, each channel in −128…127) or, with
//! `input = raw`, the raw colour (0…255), cut into `bins` bins per channel. Training
//! averages the labelled gradients that fall in each bin. Empty bins take the value of the
//! nearest filled bin (multi-source breadth-first fill over the 6-neighbour grid), so every
//! colour maps to a gradient. Lookup is one table read per pixel.

use std::collections::{HashMap, VecDeque};
use std::path::Path;

use crate::model_file::{self, ModelFile, ModelFileError};

/// What the model's colour key is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// Frame minus reference.
    Diff,
    /// The raw frame.
    Raw,
}

impl Input {
    /// `diff` or `raw`.
    pub fn as_str(self) -> &'static str {
        match self {
            Input::Diff => "diff",
            Input::Raw => "raw",
        }
    }

    /// Parse `diff` or `raw`.
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "diff" => Some(Input::Diff),
            "raw" => Some(Input::Raw),
            _ => None,
        }
    }
}

/// Default bins per channel: 4 grey levels per bin of the difference.
pub const DEFAULT_BINS: usize = 64;

/// A trained lookup table.
#[derive(Debug, Clone, PartialEq)]
pub struct LutModel {
    /// Key kind.
    pub input: Input,
    /// Bins per channel.
    pub bins: usize,
    /// Image size it was trained at.
    pub width: usize,
    /// Image size it was trained at.
    pub height: usize,
    /// Per-channel offset added to the key before binning (zero-shot transfer).
    pub offset_rgb: [f32; 3],
    /// `bins³` entries of (gx, gy).
    table: Vec<[f32; 2]>,
}

/// Accumulates labelled samples into bins.
#[derive(Debug, Clone)]
pub struct LutTrainer {
    input: Input,
    bins: usize,
    sums: Vec<[f64; 2]>,
    counts: Vec<u32>,
}

fn bin_of(v: f32, input: Input, bins: usize) -> usize {
    let unit = match input {
        Input::Diff => (v + 128.0) / 256.0,
        Input::Raw => v / 256.0,
    };
    let b = (unit * bins as f32) as isize; // NaN → 0
    b.clamp(0, bins as isize - 1) as usize
}

fn index(rgb: [f32; 3], input: Input, bins: usize) -> usize {
    let [r, g, b] = rgb.map(|c| bin_of(c, input, bins));
    (r * bins + g) * bins + b
}

impl LutTrainer {
    /// An empty trainer.
    pub fn new(input: Input, bins: usize) -> Self {
        let bins = bins.clamp(2, 256);
        Self {
            input,
            bins,
            sums: vec![[0.0; 2]; bins * bins * bins],
            counts: vec![0; bins * bins * bins],
        }
    }

    /// Add one labelled pixel: its key colour and its gradient.
    pub fn add(&mut self, rgb: [f32; 3], gx: f32, gy: f32) {
        if !(gx.is_finite() && gy.is_finite()) {
            return;
        }
        let i = index(rgb, self.input, self.bins);
        self.sums[i][0] += f64::from(gx);
        self.sums[i][1] += f64::from(gy);
        self.counts[i] += 1;
    }

    /// Bins that received samples.
    pub fn filled_bins(&self) -> usize {
        self.counts.iter().filter(|c| **c > 0).count()
    }

    /// Average, fill the empty bins, and produce the model.
    pub fn finish(self, width: usize, height: usize) -> LutModel {
        let n = self.bins;
        let mut table = vec![[0.0f32; 2]; n * n * n];
        let mut filled = vec![false; n * n * n];
        let mut queue = VecDeque::new();
        for (i, (s, c)) in self.sums.iter().zip(&self.counts).enumerate() {
            if *c > 0 {
                table[i] = [(s[0] / f64::from(*c)) as f32, (s[1] / f64::from(*c)) as f32];
                filled[i] = true;
                queue.push_back(i);
            }
        }
        while let Some(i) = queue.pop_front() {
            let (r, g, b) = (i / (n * n), (i / n) % n, i % n);
            let neighbours = [
                (r > 0).then(|| i - n * n),
                (r + 1 < n).then(|| i + n * n),
                (g > 0).then(|| i - n),
                (g + 1 < n).then(|| i + n),
                (b > 0).then(|| i - 1),
                (b + 1 < n).then(|| i + 1),
            ];
            for j in neighbours.into_iter().flatten() {
                if !filled[j] {
                    filled[j] = true;
                    table[j] = table[i];
                    queue.push_back(j);
                }
            }
        }
        LutModel {
            input: self.input,
            bins: n,
            width,
            height,
            offset_rgb: [0.0; 3],
            table,
        }
    }
}

impl LutModel {
    /// (gx, gy) for a key colour (difference or raw, per `input`).
    #[inline]
    pub fn predict(&self, rgb: [f32; 3]) -> [f32; 2] {
        let key = [
            rgb[0] + self.offset_rgb[0],
            rgb[1] + self.offset_rgb[1],
            rgb[2] + self.offset_rgb[2],
        ];
        self.table[index(key, self.input, self.bins)]
    }

    /// Save as a model file.
    pub fn save(&self, path: &Path) -> Result<(), ModelFileError> {
        let o = self.offset_rgb;
        let metadata = HashMap::from([
            ("format".to_string(), model_file::FORMAT.to_string()),
            ("version".to_string(), model_file::VERSION.to_string()),
            ("kind".to_string(), "lut".to_string()),
            ("input".to_string(), self.input.as_str().to_string()),
            ("width".to_string(), self.width.to_string()),
            ("height".to_string(), self.height.to_string()),
            (
                "offset_rgb".to_string(),
                format!("{},{},{}", o[0], o[1], o[2]),
            ),
            ("bins".to_string(), self.bins.to_string()),
        ]);
        let n = self.bins;
        let values = self.table.iter().flat_map(|g| *g).collect();
        ModelFile {
            metadata,
            tensors: vec![("lut".to_string(), vec![n, n, n, 2], values)],
        }
        .write(path)
    }

    /// Load a `kind = lut` model file.
    pub fn load(path: &Path) -> Result<Self, ModelFileError> {
        let p = path.display().to_string();
        let file = ModelFile::read(path)?;
        file.expect_key(&p, "kind", &["lut"])?;
        let input =
            Input::parse(file.expect_key(&p, "input", &["diff", "raw"])?).unwrap_or(Input::Diff);
        let num = |key: &str| -> Result<usize, ModelFileError> {
            let v = file.expect_key(&p, key, &[])?;
            v.parse().map_err(|_| ModelFileError::Metadata {
                path: p.clone(),
                key: key.into(),
                actual: Some(v.into()),
                expected: "an integer".into(),
            })
        };
        let (width, height, bins) = (num("width")?, num("height")?, num("bins")?);
        if !(2..=256).contains(&bins) {
            return Err(ModelFileError::Metadata {
                path: p,
                key: "bins".into(),
                actual: Some(bins.to_string()),
                expected: "an integer in [2, 256]".into(),
            });
        }
        let offset_rgb = parse_offset(file.metadata.get("offset_rgb").map(String::as_str))
            .ok_or_else(|| ModelFileError::Metadata {
                path: p.clone(),
                key: "offset_rgb".into(),
                actual: file.metadata.get("offset_rgb").cloned(),
                expected: "three comma-separated numbers".into(),
            })?;
        let Some((shape, values)) = file.tensor("lut") else {
            return Err(ModelFileError::Format {
                path: p,
                detail: "no tensor `lut`".into(),
            });
        };
        if shape != [bins, bins, bins, 2] || values.iter().any(|v| !v.is_finite()) {
            return Err(ModelFileError::Format {
                path: p,
                detail: format!(
                    "tensor `lut` has shape {shape:?} (expected [{bins}, {bins}, {bins}, 2]) or non-finite values"
                ),
            });
        }
        let table = values.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
        Ok(Self {
            input,
            bins,
            width,
            height,
            offset_rgb,
            table,
        })
    }
}

fn parse_offset(s: Option<&str>) -> Option<[f32; 3]> {
    let v: Vec<f32> = s?
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .ok()?;
    (v.len() == 3 && v.iter().all(|x| x.is_finite())).then(|| [v[0], v[1], v[2]])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_bins_and_fills_the_empty_ones() {
        let mut t = LutTrainer::new(Input::Diff, 8);
        t.add([0.0, 0.0, 0.0], 1.0, 2.0);
        t.add([1.0, 1.0, 1.0], 3.0, 4.0); // same bin
        t.add([100.0, -100.0, 0.0], -1.0, 0.5);
        assert_eq!(t.filled_bins(), 2);
        let m = t.finish(4, 4);
        assert_eq!(m.predict([0.5, 0.5, 0.5]), [2.0, 3.0]);
        assert_eq!(m.predict([110.0, -110.0, 0.0]), [-1.0, 0.5]);
        // An untouched colour takes its nearest filled bin.
        assert_eq!(m.predict([20.0, 10.0, 0.0]), [2.0, 3.0]);
        assert!(
            m.predict([f32::NAN, 1e9, -1e9])
                .iter()
                .all(|v| v.is_finite())
        );
    }

    #[test]
    fn model_file_round_trips_and_names_bad_metadata() {
        let mut t = LutTrainer::new(Input::Raw, 4);
        t.add([10.0, 20.0, 30.0], 0.25, -0.5);
        let mut m = t.finish(320, 240);
        m.offset_rgb = [1.0, -2.0, 0.5];
        let dir = std::env::temp_dir().join(format!("gelgrip-lut-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp dir");
        let path = dir.join("m.safetensors");
        m.save(&path).expect("save");
        assert_eq!(LutModel::load(&path).expect("load"), m);
        let mut bad = m.clone();
        bad.bins = 0;
        bad.table.clear();
        bad.save(&path).expect("save");
        let err = LutModel::load(&path).expect_err("zero bins");
        assert!(err.to_string().contains("bins"), "{err}");
        std::fs::write(&path, b"not a model").expect("write");
        let err = LutModel::load(&path).expect_err("garbage");
        assert!(err.to_string().contains("m.safetensors"), "{err}");
    }
}
