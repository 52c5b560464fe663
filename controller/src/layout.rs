//! The hand layout: which tactile sensors exist, where they sit, and their optics.
//!
//! Sensor ids follow CONTRACTS.md: `palm`, `<finger>.<link>` (`f1.tip`), or `s<N>` for the
//! generated layouts that benches use. Sensor order in the layout is the hub board index.

use std::fmt;

use serde::Deserialize;

use crate::config::{ConfigError, FieldCheck};
use crate::fingers::{self, FingerSpec, RawFinger};
use crate::markers::{MarkerGrid, RawMarkers};

/// Most sensors one hub serves (the hub address space holds 32 boards).
pub const MAX_SENSORS: usize = 32;

/// A phalanx of a finger.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Link {
    /// Nearest the palm.
    Proximal,
    /// Middle phalanx.
    Middle,
    /// Fingertip.
    Tip,
}

impl Link {
    pub(crate) fn parse(s: &str) -> Option<Self> {
        match s {
            "proximal" => Some(Link::Proximal),
            "middle" => Some(Link::Middle),
            "tip" => Some(Link::Tip),
            _ => None,
        }
    }

    /// The id word.
    pub fn as_str(self) -> &'static str {
        match self {
            Link::Proximal => "proximal",
            Link::Middle => "middle",
            Link::Tip => "tip",
        }
    }
}

/// Where a sensor belongs.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Placement {
    /// The palm sensor; it belongs to no finger.
    Palm,
    /// A sensor on finger `finger` (1-based) at `link`.
    Finger {
        /// Finger number, `f1` is 1.
        finger: u8,
        /// Phalanx.
        link: Link,
    },
    /// A generic sensor `s<N>` of a generated layout.
    Generic(u16),
}

/// A validated sensor id.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct SensorId(Placement);

impl SensorId {
    /// Parse `palm`, `f<N>.<link>` or `s<N>`.
    pub fn parse(s: &str) -> Option<Self> {
        if s == "palm" {
            return Some(Self(Placement::Palm));
        }
        if let Some((finger, link)) = s.split_once('.') {
            let n: u8 = finger.strip_prefix('f')?.parse().ok()?;
            if !(1..=9).contains(&n) || finger.len() != 2 {
                return None;
            }
            let link = Link::parse(link)?;
            return Some(Self(Placement::Finger { finger: n, link }));
        }
        let n: u16 = s.strip_prefix('s')?.parse().ok()?;
        (n >= 1 && !s.starts_with("s0")).then_some(Self(Placement::Generic(n)))
    }

    /// Where the sensor sits.
    pub fn placement(&self) -> &Placement {
        &self.0
    }

    /// The finger name (`f1`…) or `None` for the palm and generic sensors.
    pub fn finger(&self) -> Option<String> {
        match self.0 {
            Placement::Finger { finger, .. } => Some(format!("f{finger}")),
            _ => None,
        }
    }
}

impl fmt::Display for SensorId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.0 {
            Placement::Palm => f.write_str("palm"),
            Placement::Finger { finger, link } => write!(f, "f{finger}.{}", link.as_str()),
            Placement::Generic(n) => write!(f, "s{n}"),
        }
    }
}

/// Image size of a sensor's camera.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Resolution {
    /// Columns.
    pub width_px: u32,
    /// Rows.
    pub height_px: u32,
}

/// Sensor pose in the gripper base frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    /// Position in mm.
    pub xyz_mm: [f64; 3],
    /// Roll, pitch, yaw in degrees.
    pub rpy_deg: [f64; 3],
}

/// One tactile sensor of the hand.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSpec {
    /// Its id.
    pub id: SensorId,
    /// Pose on the hand.
    pub pose: Pose,
    /// Camera resolution.
    pub resolution: Resolution,
    /// Gel-surface size of one pixel, in mm.
    pub mm_per_px: f64,
    /// The dots printed on its gel (`None`: a plain gel).
    pub markers: Option<MarkerGrid>,
}

/// The whole hand: sensors in hub-board order.
#[derive(Debug, Clone, PartialEq)]
pub struct HandLayout {
    /// Layout name.
    pub name: String,
    /// Sensors; index = hub board index.
    pub sensors: Vec<SensorSpec>,
    /// Finger mechanics, in servo order (empty for generated layouts).
    pub fingers: Vec<FingerSpec>,
}

/// Default camera resolution (the paper's 320×240 JPEG).
pub const DEFAULT_RESOLUTION: Resolution = Resolution {
    width_px: 320,
    height_px: 240,
};
/// Default pixel size: a 20 mm × 15 mm gel pad imaged at 320×240.
pub const DEFAULT_MM_PER_PX: f64 = 0.0625;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLayout {
    version: i64,
    name: String,
    #[serde(default)]
    sensor_defaults: RawSensorDefaults,
    sensors: Vec<RawSensor>,
    #[serde(default)]
    fingers: Vec<RawFinger>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawSensorDefaults {
    resolution: Option<[u32; 2]>,
    mm_per_px: Option<f64>,
    markers: Option<RawMarkers>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSensor {
    id: String,
    #[serde(default)]
    xyz_mm: [f64; 3],
    #[serde(default)]
    rpy_deg: [f64; 3],
    resolution: Option<[u32; 2]>,
    mm_per_px: Option<f64>,
    markers: Option<RawMarkers>,
}

impl HandLayout {
    /// A generated layout of `n` identical sensors `s1`…`sN` (for sensor-count sweeps).
    pub fn generated(n: usize) -> Result<Self, ConfigError> {
        let check = FieldCheck::new("<generated layout>");
        check.range("sensors", n as f64, 1.0, MAX_SENSORS as f64)?;
        Ok(Self {
            name: format!("generated-{n}"),
            sensors: (1..=n)
                .map(|i| SensorSpec {
                    id: SensorId(Placement::Generic(i as u16)),
                    pose: Pose::default(),
                    resolution: DEFAULT_RESOLUTION,
                    mm_per_px: DEFAULT_MM_PER_PX,
                    markers: None,
                })
                .collect(),
            fingers: Vec::new(),
        })
    }

    /// Parse a layout file's text; `file` names it in errors.
    pub fn from_toml(file: &str, text: &str) -> Result<Self, ConfigError> {
        let check = FieldCheck::new(file);
        let raw: RawLayout = check.parse(text)?;
        check.version(raw.version)?;
        let n = raw.sensors.len();
        check.range("sensors (count)", n as f64, 1.0, MAX_SENSORS as f64)?;
        let mut sensors: Vec<SensorSpec> = Vec::with_capacity(n);
        for (i, s) in raw.sensors.into_iter().enumerate() {
            let field = |k: &str| format!("sensors[{i}].{k}");
            let id = SensorId::parse(&s.id).ok_or_else(|| {
                check.invalid(
                    &field("id"),
                    &s.id,
                    "palm, f<1-9>.<proximal|middle|tip>, or s<N>",
                )
            })?;
            if sensors.iter().any(|o| o.id == id) {
                return Err(check.invalid(&field("id"), &s.id, "a unique sensor id"));
            }
            let [w, h] = s
                .resolution
                .or(raw.sensor_defaults.resolution)
                .unwrap_or([DEFAULT_RESOLUTION.width_px, DEFAULT_RESOLUTION.height_px]);
            check.range(&field("resolution[0]"), f64::from(w), 8.0, 4096.0)?;
            check.range(&field("resolution[1]"), f64::from(h), 8.0, 4096.0)?;
            let mm_per_px = s
                .mm_per_px
                .or(raw.sensor_defaults.mm_per_px)
                .unwrap_or(DEFAULT_MM_PER_PX);
            check.range(&field("mm_per_px"), mm_per_px, 1e-4, 10.0)?;
            let markers = match (s.markers, raw.sensor_defaults.markers) {
                (Some(m), _) => Some(m.validate(&check, &field("markers"), [w, h], mm_per_px)?),
                (None, Some(m)) => {
                    let at = format!("sensor_defaults.markers (for sensors[{i}])");
                    Some(m.validate(&check, &at, [w, h], mm_per_px)?)
                }
                (None, None) => None,
            };
            for (k, v) in s.xyz_mm.iter().chain(&s.rpy_deg).enumerate() {
                check.range(&field(&format!("pose[{k}]")), *v, -1e4, 1e4)?;
            }
            sensors.push(SensorSpec {
                id,
                pose: Pose {
                    xyz_mm: s.xyz_mm,
                    rpy_deg: s.rpy_deg,
                },
                resolution: Resolution {
                    width_px: w,
                    height_px: h,
                },
                mm_per_px,
                markers,
            });
        }
        let fingers = fingers::validate(&check, raw.fingers)?;
        check_sensors_have_phalanges(&check, &sensors, &fingers)?;
        Ok(Self {
            name: raw.name,
            sensors,
            fingers,
        })
    }

    /// The finger (index into `fingers`) and phalanx that carry sensor `index`.
    pub fn phalanx_of_sensor(&self, index: usize) -> Option<(usize, usize)> {
        let Placement::Finger { finger, link } = self.sensors.get(index)?.id.placement() else {
            return None;
        };
        let name = format!("f{finger}");
        let f = self.fingers.iter().position(|f| f.id == name)?;
        Some((f, self.fingers[f].phalanx_of(*link)?))
    }

    /// Index (hub board) of the sensor named `id`.
    pub fn index_of(&self, id: &str) -> Option<usize> {
        self.sensors.iter().position(|s| s.id.to_string() == id)
    }

    /// Sensor ids, in hub-board order.
    pub fn sensor_ids(&self) -> Vec<String> {
        self.sensors.iter().map(|s| s.id.to_string()).collect()
    }

    /// Finger ids, in the servos' order.
    pub fn finger_ids(&self) -> Vec<String> {
        self.fingers.iter().map(|f| f.id.clone()).collect()
    }

    /// Sensor ids, comma-separated (for error messages).
    pub fn id_list(&self) -> String {
        self.sensor_ids().join(", ")
    }
}

/// When a layout declares fingers, every finger sensor must sit on a declared phalanx.
fn check_sensors_have_phalanges(
    check: &FieldCheck,
    sensors: &[SensorSpec],
    fingers: &[FingerSpec],
) -> Result<(), ConfigError> {
    if fingers.is_empty() {
        return Ok(());
    }
    for (i, s) in sensors.iter().enumerate() {
        if let Placement::Finger { finger, link } = s.id.placement() {
            let name = format!("f{finger}");
            let found = fingers
                .iter()
                .find(|f| f.id == name)
                .and_then(|f| f.phalanx_of(*link));
            if found.is_none() {
                return Err(check.invalid(
                    &format!("sensors[{i}].id"),
                    &s.id,
                    "a sensor on a finger and phalanx declared under [[fingers]]",
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_parse_and_print() {
        for ok in ["palm", "f1.tip", "f3.middle", "f5.proximal", "s1", "s32"] {
            let id = SensorId::parse(ok).expect(ok);
            assert_eq!(id.to_string(), ok);
        }
        for bad in [
            "", "f0.tip", "f1.nail", "f1", "s0", "s01", "hand", "f10.tip",
        ] {
            assert!(SensorId::parse(bad).is_none(), "{bad}");
        }
        assert_eq!(
            SensorId::parse("f2.tip").and_then(|i| i.finger()),
            Some("f2".into())
        );
    }

    #[test]
    fn duplicate_ids_and_bad_ranges_name_the_field() {
        let text =
            "version = 1\nname = \"x\"\n[[sensors]]\nid = \"palm\"\n[[sensors]]\nid = \"palm\"\n";
        let err = HandLayout::from_toml("l.toml", text).expect_err("dup");
        assert!(err.to_string().contains("sensors[1].id"), "{err}");
        let text = "version = 1\nname = \"x\"\n[[sensors]]\nid = \"palm\"\nmm_per_px = -1.0\n";
        let err = HandLayout::from_toml("l.toml", text).expect_err("range");
        assert!(err.to_string().contains("sensors[0].mm_per_px"), "{err}");
    }

    #[test]
    fn generated_layouts_cover_1_to_32() {
        assert_eq!(
            HandLayout::generated(1).map(|l| l.sensors.len()).ok(),
            Some(1)
        );
        let l = HandLayout::generated(32).expect("32");
        assert_eq!(l.sensors[31].id.to_string(), "s32");
        assert!(HandLayout::generated(0).is_err());
        assert!(HandLayout::generated(33).is_err());
    }
}
