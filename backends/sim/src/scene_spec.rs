//! Scene files (`configs/scenes/*.toml`): the object the gripper meets, as primitives with
//! physical properties, validated into [`SceneSpec`].
//!
//! A scene declares only what it needs: a rigid object has no stiffness, an uncrushable one
//! no crush force, and only the screwdriver has a trigger and a bolt. The object is held in
//! its pose (by a table or fixture) until `release_after_s`; from then on gravity pulls it
//! along `slip_dir` and only the grip's friction and contact normals hold it.

use glam::DVec3;
use serde::Deserialize;

use gelgrip_controller::config::{ConfigError, FieldCheck};
use gelgrip_controller::layout::HandLayout;

use crate::load::{LoadSpec, RawLoad};
use crate::shapes::{Placed, Primitive, rotation_from_rpy_deg};

/// The screwdriver's trigger: a part that moves along `travel_dir` when pressed.
#[derive(Debug, Clone, PartialEq)]
pub struct TriggerSpec {
    /// Its shape at rest, in the object frame.
    pub shape: Placed,
    /// Unit direction the trigger moves when pressed, object frame.
    pub travel_dir: DVec3,
    /// Full travel, mm; the switch closes at the end of travel.
    pub travel_mm: f64,
    /// Return-spring force at rest, N.
    pub preload_n: f64,
    /// Force that pushes the trigger to the end of its travel (the switch force), N.
    pub switch_force_n: f64,
}

/// The bolt the screwdriver drives: its reaction torque rises once it seats.
#[derive(Debug, Clone, PartialEq)]
pub struct BoltSpec {
    /// Screwdriver speed with no load, rpm.
    pub free_rpm: f64,
    /// Torque while the bolt runs in freely, N·m.
    pub run_torque_nm: f64,
    /// Turns before the head seats.
    pub seat_after_turns: f64,
    /// Torque rise per turn after seating, N·m.
    pub tighten_nm_per_turn: f64,
    /// The screwdriver's clutch torque: the bolt counts as tight here and the tool stalls.
    pub stall_torque_nm: f64,
    /// Lever from the tool axis to the grip: the hand feels torque / lever, mm.
    pub lever_mm: f64,
    /// Compliance of the tool's hold on the bolt (bit play, shaft wind-up), seen at the
    /// grip: under a reaction R the handle turns into the hand by R × this, mm per N (0 =
    /// rigid, and the hand feels the reaction only once it overcomes friction).
    pub deflection_mm_per_n: f64,
}

/// The object.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectSpec {
    /// Human-readable name (reported as the run's `object`).
    pub name: String,
    /// The union of these shapes, in the object frame.
    pub shapes: Vec<Placed>,
    /// Object frame origin in the gripper frame, mm.
    pub position_mm: DVec3,
    /// Object orientation in the gripper frame.
    pub rotation: glam::DQuat,
    /// Mass, kg.
    pub mass_kg: f64,
    /// Coulomb friction coefficient against the gel.
    pub friction: f64,
    /// Local contact stiffness of the object, N/mm (`None` = rigid).
    pub stiffness_n_per_mm: Option<f64>,
    /// A single contact force above this crushes the object, N (`None` = uncrushable).
    pub crush_force_n: Option<f64>,
    /// Stiffness multiplier once crushed.
    pub crushed_stiffness_factor: f64,
    /// The screwdriver's trigger.
    pub trigger: Option<TriggerSpec>,
    /// The bolt the screwdriver drives.
    pub bolt: Option<BoltSpec>,
    /// A pull along `slip_dir` (`[object.load]`).
    pub load: Option<LoadSpec>,
}

/// A validated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSpec {
    /// Scene name.
    pub name: String,
    /// What the scene shows.
    pub description: String,
    /// The file it came from.
    pub file: String,
    /// The object.
    pub object: ObjectSpec,
    /// Unit gravity direction in the gripper frame.
    pub gravity_dir: DVec3,
    /// Unit direction the object may slip along once released, gripper frame.
    pub slip_dir: DVec3,
    /// When the fixture lets go, s after start (`None` = held throughout).
    pub release_after_s: Option<f64>,
    /// Sensors (layout indices) that closing the fingers should touch.
    pub expect_contact: Vec<usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    version: i64,
    name: String,
    #[serde(default)]
    description: String,
    expect_contact: Vec<String>,
    #[serde(default = "default_gravity")]
    gravity_dir: [f64; 3],
    release_after_s: Option<f64>,
    object: RawObject,
}

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawObject {
    name: String,
    #[serde(default)]
    xyz_mm: [f64; 3],
    #[serde(default)]
    rpy_deg: [f64; 3],
    mass_g: f64,
    friction: f64,
    stiffness_n_per_mm: Option<f64>,
    crush_force_n: Option<f64>,
    #[serde(default = "default_crushed_factor")]
    crushed_stiffness_factor: f64,
    slip_dir: Option<[f64; 3]>,
    shapes: Vec<RawShape>,
    trigger: Option<RawTrigger>,
    bolt: Option<RawBolt>,
    load: Option<RawLoad>,
}

fn default_crushed_factor() -> f64 {
    0.2
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawShape {
    kind: String,
    radius_mm: Option<f64>,
    radii_mm: Option<[f64; 3]>,
    length_mm: Option<f64>,
    size_mm: Option<[f64; 3]>,
    #[serde(default)]
    xyz_mm: [f64; 3],
    #[serde(default)]
    rpy_deg: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTrigger {
    shape: RawShape,
    travel_dir: [f64; 3],
    travel_mm: f64,
    preload_n: f64,
    switch_force_n: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBolt {
    free_rpm: f64,
    run_torque_nm: f64,
    seat_after_turns: f64,
    tighten_nm_per_turn: f64,
    stall_torque_nm: f64,
    lever_mm: f64,
    #[serde(default)]
    deflection_mm_per_n: f64,
}

fn unit(check: &FieldCheck, field: &str, v: [f64; 3]) -> Result<DVec3, ConfigError> {
    let d = DVec3::from_array(v);
    if !d.is_finite() || d.length() < 1e-9 {
        return Err(check.invalid(field, format!("{v:?}"), "a non-zero direction"));
    }
    Ok(d.normalize())
}

fn positive(check: &FieldCheck, field: &str, v: Option<f64>, max: f64) -> Result<f64, ConfigError> {
    let v = v.ok_or_else(|| check.invalid(field, "(missing)", "a value for this kind"))?;
    check.range(field, v, 1e-3, max)
}

fn shape(check: &FieldCheck, field: &str, s: &RawShape) -> Result<Placed, ConfigError> {
    let f = |k: &str| format!("{field}.{k}");
    let primitive = match s.kind.as_str() {
        "sphere" => Primitive::Sphere {
            radius_mm: positive(check, &f("radius_mm"), s.radius_mm, 1e3)?,
        },
        "ellipsoid" => {
            let r = s.radii_mm.ok_or_else(|| {
                check.invalid(&f("radii_mm"), "(missing)", "three semi-axes in mm")
            })?;
            for (k, v) in r.iter().enumerate() {
                check.range(&f(&format!("radii_mm[{k}]")), *v, 1e-3, 1e3)?;
            }
            Primitive::Ellipsoid {
                radii_mm: DVec3::from_array(r),
            }
        }
        "cylinder" => Primitive::Cylinder {
            radius_mm: positive(check, &f("radius_mm"), s.radius_mm, 1e3)?,
            length_mm: positive(check, &f("length_mm"), s.length_mm, 1e4)?,
        },
        "cuboid" => {
            let size = s.size_mm.ok_or_else(|| {
                check.invalid(&f("size_mm"), "(missing)", "three edge lengths in mm")
            })?;
            for (k, v) in size.iter().enumerate() {
                check.range(&f(&format!("size_mm[{k}]")), *v, 1e-3, 1e4)?;
            }
            Primitive::Cuboid {
                size_mm: DVec3::from_array(size),
            }
        }
        other => {
            return Err(check.invalid(&f("kind"), other, "sphere | ellipsoid | cylinder | cuboid"));
        }
    };
    for (k, v) in s.xyz_mm.iter().chain(&s.rpy_deg).enumerate() {
        check.range(&f(&format!("pose[{k}]")), *v, -1e4, 1e4)?;
    }
    Ok(Placed {
        primitive,
        offset_mm: DVec3::from_array(s.xyz_mm),
        rotation: rotation_from_rpy_deg(s.rpy_deg),
    })
}

impl SceneSpec {
    /// Parse a scene file's text for `layout`; `file` names it in errors.
    pub fn from_toml(file: &str, text: &str, layout: &HandLayout) -> Result<Self, ConfigError> {
        let check = FieldCheck::new(file);
        let raw: RawScene = check.parse(text)?;
        check.version(raw.version)?;
        let o = raw.object;
        check.range("object.shapes (count)", o.shapes.len() as f64, 1.0, 32.0)?;
        let shapes = o
            .shapes
            .iter()
            .enumerate()
            .map(|(i, s)| shape(&check, &format!("object.shapes[{i}]"), s))
            .collect::<Result<Vec<_>, _>>()?;
        for (k, v) in o.xyz_mm.iter().chain(&o.rpy_deg).enumerate() {
            check.range(&format!("object.pose[{k}]"), *v, -1e4, 1e4)?;
        }
        let trigger = o
            .trigger
            .as_ref()
            .map(|t| trigger_spec(&check, t))
            .transpose()?;
        let bolt = match &o.bolt {
            None => None,
            Some(_) if trigger.is_none() => {
                return Err(check.invalid(
                    "object.bolt",
                    "a bolt",
                    "a bolt only with an [object.trigger] that starts the tool",
                ));
            }
            Some(b) => Some(bolt_spec(&check, b)?),
        };
        let stiffness_n_per_mm = o
            .stiffness_n_per_mm
            .map(|k| check.range("object.stiffness_n_per_mm", k, 1e-3, 1e6))
            .transpose()?;
        let crush_force_n = o
            .crush_force_n
            .map(|f| check.range("object.crush_force_n", f, 1e-3, 1e5))
            .transpose()?;
        let gravity_dir = unit(&check, "gravity_dir", raw.gravity_dir)?;
        let slip_dir = match o.slip_dir {
            Some(d) => unit(&check, "object.slip_dir", d)?,
            None => gravity_dir,
        };
        let release_after_s = raw
            .release_after_s
            .map(|t| check.range("release_after_s", t, 0.0, 1e6))
            .transpose()?;
        let mut expect_contact = Vec::with_capacity(raw.expect_contact.len());
        for (i, id) in raw.expect_contact.iter().enumerate() {
            let Some(idx) = layout.index_of(id) else {
                let expected = format!("a sensor of the layout: {}", layout.id_list());
                return Err(check.invalid(&format!("expect_contact[{i}]"), id, &expected));
            };
            expect_contact.push(idx);
        }
        Ok(Self {
            name: raw.name,
            description: raw.description,
            file: file.to_string(),
            object: ObjectSpec {
                name: o.name,
                shapes,
                position_mm: DVec3::from_array(o.xyz_mm),
                rotation: rotation_from_rpy_deg(o.rpy_deg),
                mass_kg: check.range("object.mass_g", o.mass_g, 0.0, 1e5)? / 1000.0,
                friction: check.range("object.friction", o.friction, 0.0, 5.0)?,
                stiffness_n_per_mm,
                crush_force_n,
                crushed_stiffness_factor: check.range(
                    "object.crushed_stiffness_factor",
                    o.crushed_stiffness_factor,
                    1e-3,
                    1.0,
                )?,
                trigger,
                bolt,
                load: o.load.as_ref().map(|l| l.validate(&check)).transpose()?,
            },
            gravity_dir,
            slip_dir,
            release_after_s,
            expect_contact,
        })
    }
}

/// `[object.trigger]`: the tool's trigger, which the grasp presses.
fn trigger_spec(check: &FieldCheck, t: &RawTrigger) -> Result<TriggerSpec, ConfigError> {
    let preload_n = check.range("object.trigger.preload_n", t.preload_n, 0.0, 1e3)?;
    Ok(TriggerSpec {
        shape: shape(check, "object.trigger.shape", &t.shape)?,
        travel_dir: unit(check, "object.trigger.travel_dir", t.travel_dir)?,
        travel_mm: check.range("object.trigger.travel_mm", t.travel_mm, 0.1, 50.0)?,
        preload_n,
        switch_force_n: check.range(
            "object.trigger.switch_force_n",
            t.switch_force_n,
            preload_n + 1e-3,
            1e3,
        )?,
    })
}

/// `[object.bolt]`: what the tool drives once its trigger is pressed.
fn bolt_spec(check: &FieldCheck, b: &RawBolt) -> Result<BoltSpec, ConfigError> {
    let run = check.range("object.bolt.run_torque_nm", b.run_torque_nm, 0.0, 100.0)?;
    Ok(BoltSpec {
        free_rpm: check.range("object.bolt.free_rpm", b.free_rpm, 1.0, 1e4)?,
        run_torque_nm: run,
        seat_after_turns: check.range(
            "object.bolt.seat_after_turns",
            b.seat_after_turns,
            0.0,
            1e3,
        )?,
        tighten_nm_per_turn: check.range(
            "object.bolt.tighten_nm_per_turn",
            b.tighten_nm_per_turn,
            1e-3,
            1e3,
        )?,
        stall_torque_nm: check.range(
            "object.bolt.stall_torque_nm",
            b.stall_torque_nm,
            run + 1e-3,
            1e3,
        )?,
        lever_mm: check.range("object.bolt.lever_mm", b.lever_mm, 1.0, 1e3)?,
        deflection_mm_per_n: check.range(
            "object.bolt.deflection_mm_per_n",
            b.deflection_mm_per_n,
            0.0,
            1.0,
        )?,
    })
}
