//! Saving and loading an [`MlpModel`] as a model file (`kind = mlp`): tensors
//! `l{i}.weight` (`out × in`) and `l{i}.bias`, metadata as CONTRACTS.md plus `hidden` and
//! `gain_rgb`.

use std::path::Path;

use super::{INPUTS, Layer, MlpModel};
use crate::lut::Input;
use crate::model_file::{self, ModelFile, ModelFileError, parse_rgb, rgb_string};

impl MlpModel {
    /// Save as a model file.
    pub fn save(&self, path: &Path) -> Result<(), ModelFileError> {
        let mut metadata = model_file::base_metadata(
            "mlp",
            self.input.as_str(),
            (self.width, self.height),
            self.offset_rgb,
        );
        metadata.extend([
            ("gain_rgb".to_string(), rgb_string(self.gain_rgb)),
            ("hidden".to_string(), self.hidden.to_string()),
            ("activation".to_string(), "tanh".to_string()),
        ]);
        model_file::put_mm_per_px(&mut metadata, self.mm_per_px);
        model_file::put_slopes(&mut metadata, self.slopes);
        let mut tensors = Vec::new();
        for (i, l) in self.layers.iter().enumerate() {
            tensors.push((
                format!("l{i}.weight"),
                vec![l.outputs, l.inputs],
                l.weight.clone(),
            ));
            tensors.push((format!("l{i}.bias"), vec![l.outputs], l.bias.clone()));
        }
        ModelFile { metadata, tensors }.write(path)
    }

    /// Load a `kind = mlp` model file.
    pub fn load(path: &Path) -> Result<Self, ModelFileError> {
        Self::from_file(&ModelFile::read(path)?, &path.display().to_string())
    }

    /// The model in an already read file (`p` names it in errors).
    pub fn from_file(file: &ModelFile, p: &str) -> Result<Self, ModelFileError> {
        file.expect_key(p, "kind", &["mlp"])?;
        let input =
            Input::parse(file.expect_key(p, "input", &Input::NAMES)?).unwrap_or(Input::Diff);
        let num = |key: &str| -> Result<usize, ModelFileError> {
            let v = file.expect_key(p, key, &[])?;
            v.parse()
                .ok()
                .filter(|n| *n > 0)
                .ok_or_else(|| ModelFileError::Metadata {
                    path: p.to_string(),
                    key: key.into(),
                    actual: Some(v.into()),
                    expected: "a positive integer".into(),
                })
        };
        let (width, height, hidden) = (num("width")?, num("height")?, num("hidden")?);
        let rgb = |key: &str, default: Option<[f32; 3]>| {
            let v = file.metadata.get(key).map(String::as_str);
            match (v, default) {
                (None, Some(d)) => Ok(d),
                _ => parse_rgb(v).ok_or_else(|| ModelFileError::Metadata {
                    path: p.to_string(),
                    key: key.into(),
                    actual: v.map(str::to_string),
                    expected: "three comma-separated numbers".into(),
                }),
            }
        };
        let offset_rgb = rgb("offset_rgb", None)?;
        let gain_rgb = rgb("gain_rgb", Some([1.0; 3]))?;
        let sizes = [INPUTS, hidden, hidden, hidden, 2];
        let mut layers = Vec::new();
        for i in 0..4 {
            let (inputs, outputs) = (sizes[i], sizes[i + 1]);
            let get = |name: String, shape: &[usize]| -> Result<Vec<f32>, ModelFileError> {
                match file.tensor(&name) {
                    Some((s, v)) if s == shape && v.iter().all(|x| x.is_finite()) => Ok(v.to_vec()),
                    Some((s, _)) => Err(ModelFileError::Format {
                        path: p.to_string(),
                        detail: format!(
                            "tensor `{name}` has shape {s:?} (expected {shape:?}) or non-finite values"
                        ),
                    }),
                    None => Err(ModelFileError::Format {
                        path: p.to_string(),
                        detail: format!("no tensor `{name}` (hidden = {hidden})"),
                    }),
                }
            };
            layers.push(Layer {
                inputs,
                outputs,
                weight: get(format!("l{i}.weight"), &[outputs, inputs])?,
                bias: get(format!("l{i}.bias"), &[outputs])?,
            });
        }
        Ok(Self {
            input,
            width,
            height,
            hidden,
            layers,
            offset_rgb,
            gain_rgb,
            mm_per_px: model_file::mm_per_px(file, p)?,
            slopes: model_file::slopes(file, p)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny() -> MlpModel {
        let sizes = [INPUTS, 3, 3, 3, 2];
        let layers = (0..4)
            .map(|i| Layer {
                inputs: sizes[i],
                outputs: sizes[i + 1],
                weight: (0..sizes[i] * sizes[i + 1])
                    .map(|k| k as f32 * 0.01)
                    .collect(),
                bias: vec![0.5; sizes[i + 1]],
            })
            .collect();
        MlpModel {
            input: Input::Raw,
            width: 320,
            height: 240,
            hidden: 3,
            layers,
            offset_rgb: [1.0, -2.0, 3.5],
            gain_rgb: [1.1, 0.9, 1.0],
            mm_per_px: Some(0.0625),
            slopes: crate::model_file::Slopes::Footprint,
        }
    }

    #[test]
    fn round_trips_and_rejects_missing_or_unknown_metadata() {
        let dir = std::env::temp_dir().join(format!("gelgrip-mlp-file-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("tmp dir");
        let path = dir.join("m.safetensors");
        let m = tiny();
        m.save(&path).expect("save");
        assert_eq!(MlpModel::load(&path).expect("load"), m);

        let mut file = ModelFile::read(&path).expect("read");
        assert_eq!(
            file.metadata.get("mm_per_px").map(String::as_str),
            Some("0.0625")
        );
        // A file written before `mm_per_px` (or `slopes`) was recorded loads without it
        // (forward differences).
        let mut old = file.clone();
        old.metadata.remove("mm_per_px");
        old.metadata.remove("slopes");
        old.write(&path).expect("write");
        let loaded = MlpModel::load(&path).expect("load");
        assert_eq!(loaded.mm_per_px, None);
        assert_eq!(loaded.slopes, crate::model_file::Slopes::Forward);
        for (key, value, expect) in [
            ("version", Some("7"), "metadata `version` is Some(\"7\")"),
            ("hidden", None, "metadata `hidden` is None"),
            ("offset_rgb", Some("1,2"), "metadata `offset_rgb`"),
            ("kind", Some("lut"), "expected mlp"),
            (
                "mm_per_px",
                Some("-0.1"),
                "metadata `mm_per_px` is Some(\"-0.1\")",
            ),
            ("mm_per_px", Some("NaN"), "expected a positive number"),
        ] {
            let mut f = file.clone();
            match value {
                Some(v) => f.metadata.insert(key.into(), v.into()),
                None => f.metadata.remove(key),
            };
            f.write(&path).expect("write");
            let err = MlpModel::load(&path).expect_err(key).to_string();
            assert!(
                err.contains(expect) && err.contains("m.safetensors"),
                "{err}"
            );
        }
        file.metadata.remove("format");
        file.write(&path).expect("write");
        let err = MlpModel::load(&path).expect_err("no format").to_string();
        assert!(err.contains("metadata `format` is None"), "{err}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
