//! The `[pipeline]` section: stage choices by registered name, with per-sensor overrides.
//!
//! ```toml
//! [pipeline]
//! decode = "jpeg"            # jpeg
//! decode_scale = 1           # 1 | 2 | 4
//! undistort = "none"         # none | fisheye (then [pipeline.fisheye] fx, fy, cx, cy, k)
//! reference = "static"       # static | drift
//! reference_alpha = 0.02     # drift: refresh rate per no-contact frame
//! diff = "diff"
//! gradient = "lut"           # lut | mlp (mlp needs `model`)
//! model = "models/lut.safetensors"   # optional for lut; relative to this file
//! mlp_mode = "contact"       # mlp: contact (pixels above the noise) | dense
//! depth = "dct"              # dst | dct | none
//! contact = "threshold"
//! stiffness_n_per_mm3 = 0.1
//!
//! [[pipeline.sensors]]       # any key above, for one sensor
//! id = "palm"
//! depth = "none"
//! ```

use std::path::PathBuf;

use serde::Deserialize;

use gelgrip_controller::config::{BackendSection, ConfigError, FieldCheck};
use gelgrip_controller::layout::HandLayout;

use crate::contact::DEFAULT_STIFFNESS_N_PER_MM3;
use crate::gradient::MlpMode;
use crate::pipeline::STAGES;
use crate::poisson::Solver;
use crate::undistort::Fisheye;

/// One sensor's validated stage choices.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorStages {
    /// Decode scale: 1, 2 or 4.
    pub decode_scale: usize,
    /// Lens model (`None` = stage `none`).
    pub undistort: Option<Fisheye>,
    /// Reference refresh rate (0 = stage `static`).
    pub reference_alpha: f32,
    /// Model file for the gradient stage, if configured.
    pub model: Option<PathBuf>,
    /// Gradient `mlp` and where it runs (`None` = gradient `lut`).
    pub mlp: Option<MlpMode>,
    /// Depth solver (`None` = stage `none`).
    pub solver: Option<Solver>,
    /// Force-proxy stiffness, N/mm³.
    pub stiffness_n_per_mm3: f64,
}

/// Stage choices for every sensor of the layout, in layout order.
#[derive(Debug, Clone, PartialEq)]
pub struct PipelineConfig {
    /// Per sensor.
    pub sensors: Vec<SensorStages>,
}

#[derive(Deserialize, Default, Clone)]
#[serde(deny_unknown_fields)]
struct RawStages {
    decode: Option<String>,
    decode_scale: Option<i64>,
    undistort: Option<String>,
    reference: Option<String>,
    reference_alpha: Option<f64>,
    diff: Option<String>,
    gradient: Option<String>,
    model: Option<String>,
    mlp_mode: Option<String>,
    depth: Option<String>,
    contact: Option<String>,
    stiffness_n_per_mm3: Option<f64>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawFisheye {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(default)]
    k: [f64; 4],
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawPipeline {
    #[serde(flatten)]
    stages: RawStages,
    fisheye: Option<RawFisheye>,
    #[serde(default)]
    sensors: Vec<RawSensor>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSensor {
    id: String,
    #[serde(flatten)]
    stages: RawStages,
}

fn merge(base: &RawStages, over: &RawStages) -> RawStages {
    let pick = |a: &Option<String>, b: &Option<String>| b.clone().or_else(|| a.clone());
    RawStages {
        decode: pick(&base.decode, &over.decode),
        decode_scale: over.decode_scale.or(base.decode_scale),
        undistort: pick(&base.undistort, &over.undistort),
        reference: pick(&base.reference, &over.reference),
        reference_alpha: over.reference_alpha.or(base.reference_alpha),
        diff: pick(&base.diff, &over.diff),
        gradient: pick(&base.gradient, &over.gradient),
        model: pick(&base.model, &over.model),
        mlp_mode: pick(&base.mlp_mode, &over.mlp_mode),
        depth: pick(&base.depth, &over.depth),
        contact: pick(&base.contact, &over.contact),
        stiffness_n_per_mm3: over.stiffness_n_per_mm3.or(base.stiffness_n_per_mm3),
    }
}

fn choose<'a>(
    check: &FieldCheck,
    field: &str,
    slot: &str,
    value: &'a Option<String>,
    default: &'a str,
) -> Result<&'a str, ConfigError> {
    let v = value.as_deref().unwrap_or(default);
    let names = STAGES
        .iter()
        .find(|(s, _)| *s == slot)
        .map(|(_, n)| *n)
        .unwrap_or(&[]);
    if names.contains(&v) {
        return Ok(v);
    }
    Err(check.invalid(field, v, &names.join(" | ")))
}

impl PipelineConfig {
    /// Validate `section` (`[pipeline]`) for `layout`.
    pub fn from_section(
        section: &BackendSection,
        layout: &HandLayout,
    ) -> Result<Self, ConfigError> {
        let check = &section.check;
        let raw: RawPipeline = check.parse_table(&section.prefix, &section.table)?;
        let fisheye = raw.fisheye.as_ref().map(|f| Fisheye {
            fx: f.fx,
            fy: f.fy,
            cx: f.cx,
            cy: f.cy,
            k: f.k,
        });
        let mut per_sensor = vec![raw.stages.clone(); layout.sensors.len()];
        let mut prefixes: Vec<String> = vec!["pipeline".into(); layout.sensors.len()];
        for (i, s) in raw.sensors.iter().enumerate() {
            let Some(idx) = layout.index_of(&s.id) else {
                let expected = format!("a sensor of the layout: {}", layout.id_list());
                return Err(check.invalid(&format!("pipeline.sensors[{i}].id"), &s.id, &expected));
            };
            per_sensor[idx] = merge(&raw.stages, &s.stages);
            prefixes[idx] = format!("pipeline.sensors[{i}]");
        }
        let sensors = per_sensor
            .iter()
            .zip(&prefixes)
            .map(|(r, p)| stages(check, p, r, fisheye, &section.base_dir))
            .collect::<Result<_, _>>()?;
        Ok(Self { sensors })
    }
}

fn stages(
    check: &FieldCheck,
    p: &str,
    r: &RawStages,
    fisheye: Option<Fisheye>,
    base: &std::path::Path,
) -> Result<SensorStages, ConfigError> {
    let f = |k: &str| format!("{p}.{k}");
    choose(check, &f("decode"), "decode", &r.decode, "jpeg")?;
    choose(check, &f("diff"), "diff", &r.diff, "diff")?;
    let mlp = match choose(check, &f("gradient"), "gradient", &r.gradient, "lut")? {
        "mlp" => {
            if r.model.is_none() {
                return Err(check.invalid(
                    &f("gradient"),
                    "mlp",
                    "`model` set as well (a file from `gelgrip calibrate train --model mlp`)",
                ));
            }
            let mode = r.mlp_mode.as_deref().unwrap_or("contact");
            Some(
                MlpMode::parse(mode)
                    .ok_or_else(|| check.invalid(&f("mlp_mode"), mode, "contact | dense"))?,
            )
        }
        _ => None,
    };
    choose(check, &f("contact"), "contact", &r.contact, "threshold")?;
    let scale = r.decode_scale.unwrap_or(1);
    if ![1, 2, 4].contains(&scale) {
        return Err(check.invalid(&f("decode_scale"), scale, "1 | 2 | 4"));
    }
    let undistort = match choose(check, &f("undistort"), "undistort", &r.undistort, "none")? {
        "fisheye" => Some(fisheye.ok_or_else(|| {
            check.invalid(
                &f("undistort"),
                "fisheye",
                "a [pipeline.fisheye] table with fx, fy, cx, cy, k",
            )
        })?),
        _ => None,
    };
    let reference_alpha = match choose(check, &f("reference"), "reference", &r.reference, "static")?
    {
        "drift" => check.range(
            &f("reference_alpha"),
            r.reference_alpha.unwrap_or(0.02),
            1e-6,
            1.0,
        )? as f32,
        _ => 0.0,
    };
    let solver = Solver::parse(choose(check, &f("depth"), "depth", &r.depth, "dct")?);
    let stiffness = check.range(
        &f("stiffness_n_per_mm3"),
        r.stiffness_n_per_mm3.unwrap_or(DEFAULT_STIFFNESS_N_PER_MM3),
        0.0,
        1e6,
    )?;
    Ok(SensorStages {
        decode_scale: scale as usize,
        undistort,
        reference_alpha,
        model: r.model.as_ref().map(|m| base.join(m)),
        mlp,
        solver,
        stiffness_n_per_mm3: stiffness,
    })
}

#[cfg(test)]
mod tests_support {
    use std::sync::Arc;

    use gelgrip_controller::config::{BackendSection, DiskFiles, FieldCheck};

    pub fn section(text: &str) -> BackendSection {
        BackendSection {
            check: FieldCheck::new("g.toml"),
            prefix: "pipeline".into(),
            table: toml::from_str(text).expect("toml"),
            base_dir: "/cfg".into(),
            files: Arc::new(DiskFiles),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::section;
    use super::*;

    #[test]
    fn defaults_and_per_sensor_overrides() {
        let layout = HandLayout::generated(3).expect("layout");
        let cfg = PipelineConfig::from_section(&section("depth = \"dst\"\nmodel = \"m.safetensors\"\n[[sensors]]\nid = \"s2\"\ndepth = \"none\"\n"), &layout).expect("valid");
        assert_eq!(cfg.sensors[0].solver, Some(Solver::Dst));
        assert_eq!(cfg.sensors[1].solver, None);
        assert_eq!(
            cfg.sensors[1].model,
            Some(PathBuf::from("/cfg/m.safetensors"))
        );
        let empty = PipelineConfig::from_section(&section(""), &layout).expect("defaults");
        assert_eq!(empty.sensors[2].solver, Some(Solver::Dct));
    }

    #[test]
    fn errors_name_the_field_and_the_choices() {
        let layout = HandLayout::generated(2).expect("layout");
        let err = PipelineConfig::from_section(
            &section("[[sensors]]\nid = \"s1\"\ndepth = \"fft\"\n"),
            &layout,
        )
        .expect_err("bad");
        assert!(
            err.to_string().contains("pipeline.sensors[0].depth"),
            "{err}"
        );
        assert!(err.to_string().contains("dst | dct | none"), "{err}");
        let err =
            PipelineConfig::from_section(&section("gradient = \"mlp\""), &layout).expect_err("mlp");
        assert!(err.to_string().contains("`model` set as well"), "{err}");
        let err = PipelineConfig::from_section(
            &section("gradient = \"mlp\"\nmodel = \"m.safetensors\"\nmlp_mode = \"sparse\""),
            &layout,
        )
        .expect_err("mode");
        assert!(err.to_string().contains("contact | dense"), "{err}");
        let ok = PipelineConfig::from_section(
            &section("gradient = \"mlp\"\nmodel = \"m.safetensors\""),
            &layout,
        )
        .expect("mlp");
        assert_eq!(ok.sensors[0].mlp, Some(MlpMode::ContactOnly));
        let err = PipelineConfig::from_section(&section("undistort = \"fisheye\""), &layout)
            .expect_err("no table");
        assert!(err.to_string().contains("[pipeline.fisheye]"), "{err}");
    }
}

#[cfg(test)]
mod unknown_keys {
    use super::tests_support::section;
    use super::*;

    #[test]
    fn unknown_keys_are_rejected() {
        let layout = HandLayout::generated(2).expect("layout");
        assert!(PipelineConfig::from_section(&section("bogus = 1"), &layout).is_err());
        assert!(
            PipelineConfig::from_section(
                &section("[[sensors]]\nid = \"s1\"\nbogus = 1\n"),
                &layout
            )
            .is_err()
        );
    }
}
