//! What a run on a scene reports: which sensors touched, crush, slip and drop, the
//! screwdriver's events and the peak force per sensor, with sensors named by their ids.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::world::World;
use crate::world_log::EventKind;
use gelgrip_controller::layout::HandLayout;

/// One world event, with the sensor named.
#[derive(Debug, Serialize)]
pub struct SceneEvent {
    /// Simulated time since the run began, s.
    pub t_s: f64,
    /// What happened.
    pub kind: EventKind,
    /// The sensor involved.
    pub sensor: Option<String>,
    /// Its figure (N, mm or N·m, by kind).
    pub value: Option<f64>,
}

/// The `scene` object of `run --json`.
#[derive(Debug, Serialize)]
pub struct SceneReport {
    /// Scene name.
    pub name: String,
    /// Object name.
    pub object: String,
    /// Sensors that touched the object.
    pub touched: Vec<String>,
    /// Sensors the scene expects to touch.
    pub expect_contact: Vec<String>,
    /// `touched` equals `expect_contact`.
    pub contact_as_expected: bool,
    /// A contact force exceeded the object's crush force.
    pub crushed: bool,
    /// The force one pad may put on the object before it crushes, N (null: uncrushable).
    pub crush_force_n: Option<f64>,
    /// The object left the hand.
    pub dropped: bool,
    /// How far the object slipped, mm.
    pub slip_mm: f64,
    /// Peak normal force per touched sensor, N (simulator ground truth).
    pub peak_force_n: BTreeMap<String, f64>,
    /// Events in time order.
    pub events: Vec<SceneEvent>,
}

impl SceneReport {
    /// The report of `world`, or `None` when it has no scene.
    pub fn of(world: &World, layout: &HandLayout) -> Option<Self> {
        let scene = world.scene()?;
        let object = world.object()?;
        let name = |s: usize| layout.sensors.get(s).map(|x| x.id.to_string());
        let log = world.log();
        let touched_idx: Vec<usize> = log
            .first_contact_s()
            .iter()
            .enumerate()
            .filter_map(|(s, t)| t.map(|_| s))
            .collect();
        let mut expected_idx = scene.expect_contact.clone();
        expected_idx.sort_unstable();
        Some(Self {
            name: scene.name.clone(),
            object: object.spec().name.clone(),
            touched: touched_idx.iter().filter_map(|s| name(*s)).collect(),
            expect_contact: expected_idx.iter().filter_map(|s| name(*s)).collect(),
            contact_as_expected: touched_idx == expected_idx,
            crushed: object.crushed,
            crush_force_n: object.spec().crush_force_n,
            dropped: object.dropped,
            slip_mm: object.slip_mm,
            peak_force_n: log
                .peak_force_n()
                .iter()
                .enumerate()
                .filter(|(_, f)| **f > 0.0)
                .filter_map(|(s, f)| Some((name(s)?, (f * 1000.0).round() / 1000.0)))
                .collect(),
            events: log
                .events()
                .iter()
                .map(|e| SceneEvent {
                    t_s: e.t_s,
                    kind: e.kind,
                    sensor: e.sensor.and_then(name),
                    value: e.value,
                })
                .collect(),
        })
    }
}
