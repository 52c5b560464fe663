//! Finger geometry from the layout file: the cable-driven fingers' phalanges, joints, return
//! springs and cable routing.
//!
//! Each finger lies in a vertical plane through the palm axis. Its base joint sits at
//! `base_xyz_mm`; `yaw_deg` is the direction from the palm axis out to the finger, so
//! flexion swings the phalanges toward the axis. One servo per finger winds a cable on a
//! pulley: the cable pulls every joint through its moment arm against that joint's return
//! spring, after the cable's slack is taken up. The simulator's finger mechanics and the
//! dashboard read this; nothing here is simulator-specific (a real hand has the same
//! numbers).

use serde::Deserialize;

use crate::config::{ConfigError, FieldCheck};
use crate::layout::Link;

/// One phalanx and the joint at its base.
#[derive(Debug, Clone, PartialEq)]
pub struct PhalanxSpec {
    /// Which link it is (sensor `f<N>.<link>` sits on it).
    pub link: Link,
    /// Joint-to-joint length, mm.
    pub length_mm: f64,
    /// Angle of the phalanx at rest: relative to the palm normal for the first phalanx
    /// (negative leans outward), relative to the previous phalanx otherwise; degrees.
    pub rest_deg: f64,
    /// Largest flexion of the joint beyond rest, degrees.
    pub limit_deg: f64,
    /// Return-spring stiffness, N·mm per radian of flexion.
    pub spring_nmm_per_rad: f64,
    /// Return-spring torque at rest, N·mm (holds the finger open against cable friction).
    pub spring_preload_nmm: f64,
    /// Cable moment arm about the joint, mm.
    pub moment_arm_mm: f64,
    /// Distance from the joint to the sensor pad's centre along the phalanx, mm.
    pub pad_offset_mm: f64,
    /// Distance of the pad surface from the phalanx axis, on the inner side, mm.
    pub pad_standoff_mm: f64,
}

/// One finger.
#[derive(Debug, Clone, PartialEq)]
pub struct FingerSpec {
    /// `f1`, `f2`, …
    pub id: String,
    /// Base joint position in the gripper frame, mm.
    pub base_xyz_mm: [f64; 3],
    /// Direction from the palm axis to the finger, degrees about +z.
    pub yaw_deg: f64,
    /// Servo pulley radius, mm.
    pub pulley_radius_mm: f64,
    /// Cable slack at servo position 0, mm.
    pub cable_slack_mm: f64,
    /// Servo travel from open to fully wound, degrees (goal positions are clamped to it).
    pub servo_range_deg: f64,
    /// Phalanges from the palm outward.
    pub phalanges: Vec<PhalanxSpec>,
}

impl FingerSpec {
    /// The phalanx carrying `link`, as an index.
    pub fn phalanx_of(&self, link: Link) -> Option<usize> {
        self.phalanges.iter().position(|p| p.link == link)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawFinger {
    id: String,
    base_xyz_mm: [f64; 3],
    yaw_deg: f64,
    #[serde(default = "default_pulley")]
    pulley_radius_mm: f64,
    #[serde(default)]
    cable_slack_mm: f64,
    #[serde(default = "default_servo_range")]
    servo_range_deg: f64,
    phalanges: Vec<RawPhalanx>,
}

fn default_pulley() -> f64 {
    10.0
}

fn default_servo_range() -> f64 {
    180.0
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPhalanx {
    link: String,
    length_mm: f64,
    #[serde(default)]
    rest_deg: f64,
    limit_deg: f64,
    spring_nmm_per_rad: f64,
    #[serde(default)]
    spring_preload_nmm: f64,
    moment_arm_mm: f64,
    pad_offset_mm: f64,
    pad_standoff_mm: f64,
}

/// Validate the `[[fingers]]` tables of a layout.
pub(crate) fn validate(
    check: &FieldCheck,
    raw: Vec<RawFinger>,
) -> Result<Vec<FingerSpec>, ConfigError> {
    let mut fingers: Vec<FingerSpec> = Vec::with_capacity(raw.len());
    for (i, f) in raw.into_iter().enumerate() {
        let field = |k: &str| format!("fingers[{i}].{k}");
        let valid_id =
            f.id.strip_prefix('f')
                .and_then(|n| n.parse::<u8>().ok())
                .is_some_and(|n| (1..=9).contains(&n) && f.id.len() == 2);
        if !valid_id || fingers.iter().any(|o| o.id == f.id) {
            return Err(check.invalid(&field("id"), &f.id, "a unique finger id f1…f9"));
        }
        for (k, v) in f.base_xyz_mm.iter().enumerate() {
            check.range(&field(&format!("base_xyz_mm[{k}]")), *v, -1e3, 1e3)?;
        }
        check.range(&field("yaw_deg"), f.yaw_deg, -720.0, 720.0)?;
        check.range(&field("pulley_radius_mm"), f.pulley_radius_mm, 1.0, 100.0)?;
        check.range(&field("cable_slack_mm"), f.cable_slack_mm, 0.0, 50.0)?;
        check.range(&field("servo_range_deg"), f.servo_range_deg, 1.0, 3600.0)?;
        check.range(
            &field("phalanges (count)"),
            f.phalanges.len() as f64,
            1.0,
            4.0,
        )?;
        let mut phalanges: Vec<PhalanxSpec> = Vec::with_capacity(f.phalanges.len());
        for (j, p) in f.phalanges.into_iter().enumerate() {
            let pf = |k: &str| format!("fingers[{i}].phalanges[{j}].{k}");
            let link = Link::parse(&p.link)
                .filter(|l| phalanges.iter().all(|o| o.link != *l))
                .ok_or_else(|| {
                    check.invalid(&pf("link"), &p.link, "a unique proximal | middle | tip")
                })?;
            phalanges.push(PhalanxSpec {
                link,
                length_mm: check.range(&pf("length_mm"), p.length_mm, 1.0, 500.0)?,
                rest_deg: check.range(&pf("rest_deg"), p.rest_deg, -90.0, 90.0)?,
                limit_deg: check.range(&pf("limit_deg"), p.limit_deg, 0.0, 180.0)?,
                spring_nmm_per_rad: check.range(
                    &pf("spring_nmm_per_rad"),
                    p.spring_nmm_per_rad,
                    1e-3,
                    1e6,
                )?,
                spring_preload_nmm: check.range(
                    &pf("spring_preload_nmm"),
                    p.spring_preload_nmm,
                    0.0,
                    1e6,
                )?,
                moment_arm_mm: check.range(&pf("moment_arm_mm"), p.moment_arm_mm, 0.1, 100.0)?,
                pad_offset_mm: check.range(&pf("pad_offset_mm"), p.pad_offset_mm, 0.0, 500.0)?,
                pad_standoff_mm: check.range(
                    &pf("pad_standoff_mm"),
                    p.pad_standoff_mm,
                    0.0,
                    100.0,
                )?,
            });
        }
        fingers.push(FingerSpec {
            id: f.id,
            base_xyz_mm: f.base_xyz_mm,
            yaw_deg: f.yaw_deg,
            pulley_radius_mm: f.pulley_radius_mm,
            cable_slack_mm: f.cable_slack_mm,
            servo_range_deg: f.servo_range_deg,
            phalanges,
        });
    }
    Ok(fingers)
}
