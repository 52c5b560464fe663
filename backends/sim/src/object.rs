//! The scene object at run time: its pose (with slip), crush state, and the screwdriver's
//! trigger and bolt.
//!
//! The object has one degree of freedom, a slip along the scene's `slip_dir`; everything
//! else is held where the scene put it ("model only what the scene declares": no rigid-body
//! engine). The trigger slides along its travel against a return spring, and the switch
//! closes at the end of travel; then the bolt turns, its torque rising once seated, until
//! the tool's clutch torque stalls it.

use glam::{DQuat, DVec3};

use crate::contact::Surface;
use crate::scene_spec::{BoltSpec, ObjectSpec, TriggerSpec};

/// The trigger counts as released below this share of its travel.
const SWITCH_RELEASE_SHARE: f64 = 0.7;
/// The switch closes within this distance of the end of travel, mm.
const SWITCH_CLOSE_MARGIN_MM: f64 = 0.05;

/// The object now.
#[derive(Debug, Clone)]
pub struct ObjectState {
    spec: ObjectSpec,
    slip_dir: DVec3,
    local_bounds: (DVec3, f64),
    /// Displacement along `slip_dir`, mm.
    pub slip_mm: f64,
    /// Elastic turn of the handle into the hand under the bolt's reaction, at the grip,
    /// along `slip_dir`, mm.
    pub deflection_mm: f64,
    /// Trigger displacement, mm.
    pub trigger_mm: f64,
    /// The tool's switch is closed.
    pub switch_on: bool,
    /// Bolt turns so far.
    pub bolt_turns: f64,
    /// Torque the tool applies to the bolt now, N·m.
    pub bolt_torque_nm: f64,
    /// The bolt reached the clutch torque.
    pub bolt_tight: bool,
    /// A contact force exceeded the crush force.
    pub crushed: bool,
    /// The object left the hand.
    pub dropped: bool,
}

fn union_bounds(spec: &ObjectSpec) -> (DVec3, f64) {
    let mut parts: Vec<(DVec3, f64)> = spec.shapes.iter().map(|s| s.bounds()).collect();
    if let Some(t) = &spec.trigger {
        let (c, r) = t.shape.bounds();
        parts.push((c, r + t.travel_mm));
    }
    let n = parts.len().max(1) as f64;
    let center = parts.iter().map(|(c, _)| *c).sum::<DVec3>() / n;
    let radius = parts
        .iter()
        .map(|(c, r)| (*c - center).length() + r)
        .fold(0.0, f64::max);
    (center, radius)
}

impl ObjectState {
    /// The object as the scene places it.
    pub fn new(spec: ObjectSpec, slip_dir: DVec3) -> Self {
        Self {
            local_bounds: union_bounds(&spec),
            spec,
            slip_dir,
            slip_mm: 0.0,
            deflection_mm: 0.0,
            trigger_mm: 0.0,
            switch_on: false,
            bolt_turns: 0.0,
            bolt_torque_nm: 0.0,
            bolt_tight: false,
            crushed: false,
            dropped: false,
        }
    }

    /// Replace its tangential load.
    pub fn set_load(&mut self, load: Option<crate::load::LoadSpec>) {
        self.spec.load = load;
    }

    /// Its description.
    pub fn spec(&self) -> &ObjectSpec {
        &self.spec
    }

    fn origin(&self) -> DVec3 {
        self.spec.position_mm + self.slip_dir * (self.slip_mm + self.deflection_mm)
    }

    fn rotation(&self) -> DQuat {
        self.spec.rotation
    }

    /// Bounding radius, mm.
    pub fn radius_mm(&self) -> f64 {
        self.local_bounds.1
    }

    /// Move the trigger toward balance between the finger's `force_n` on it (over
    /// `area_mm2`) and its spring, then update the switch.
    pub fn update_trigger(&mut self, force_n: f64, area_mm2: f64) {
        let Some(t) = self.spec.trigger.clone() else {
            return;
        };
        let k = trigger_rate(&t);
        let spring = t.preload_n + k * self.trigger_mm;
        let contact_rate = crate::contact::GEL_N_PER_MM3 * area_mm2.max(1.0);
        let step = 0.5 * (force_n - spring) / (k + contact_rate);
        self.trigger_mm = (self.trigger_mm + step).clamp(0.0, t.travel_mm);
        if self.trigger_mm >= t.travel_mm - SWITCH_CLOSE_MARGIN_MM {
            self.switch_on = true;
        } else if self.trigger_mm < SWITCH_RELEASE_SHARE * t.travel_mm {
            self.switch_on = false;
        }
    }

    /// Run the tool for `dt_s`; returns the reaction force the hand feels, N.
    pub fn update_bolt(&mut self, dt_s: f64) -> f64 {
        let Some(b) = self.spec.bolt.clone() else {
            return 0.0;
        };
        if !self.switch_on {
            self.bolt_torque_nm = 0.0;
            self.deflection_mm = 0.0;
            return 0.0;
        }
        let torque = bolt_torque(&b, self.bolt_turns);
        if torque >= b.stall_torque_nm {
            self.bolt_tight = true;
            self.bolt_torque_nm = b.stall_torque_nm;
        } else {
            // The motor slows as the torque rises, down to the clutch's slipping speed.
            let rpm = b.free_rpm * (1.0 - torque / b.stall_torque_nm).max(0.1);
            self.bolt_turns += rpm / 60.0 * dt_s;
            self.bolt_torque_nm = bolt_torque(&b, self.bolt_turns).min(b.stall_torque_nm);
        }
        let reaction_n = self.bolt_torque_nm / (b.lever_mm / 1000.0);
        self.deflection_mm = reaction_n * b.deflection_mm_per_n;
        reaction_n
    }
}

fn trigger_rate(t: &TriggerSpec) -> f64 {
    (t.switch_force_n - t.preload_n) / t.travel_mm
}

fn bolt_torque(b: &BoltSpec, turns: f64) -> f64 {
    b.run_torque_nm + b.tighten_nm_per_turn * (turns - b.seat_after_turns).max(0.0)
}

impl Surface for ObjectState {
    fn probe(&self, p: DVec3) -> (f64, u8) {
        if self.dropped {
            return (f64::INFINITY, 0);
        }
        let local = self.rotation().inverse() * (p - self.origin());
        let body = self
            .spec
            .shapes
            .iter()
            .map(|s| s.distance_mm(local))
            .fold(f64::INFINITY, f64::min);
        match &self.spec.trigger {
            Some(t) => {
                let d = t.shape.distance_mm(local - t.travel_dir * self.trigger_mm);
                if d < body { (d, 1) } else { (body, 0) }
            }
            None => (body, 0),
        }
    }

    fn bounds(&self) -> (DVec3, f64) {
        if self.dropped {
            return (DVec3::splat(1e9), 0.0);
        }
        let (c, r) = self.local_bounds;
        (self.origin() + self.rotation() * c, r)
    }

    fn stiffness_n_per_mm(&self) -> Option<f64> {
        let k = self.spec.stiffness_n_per_mm?;
        Some(if self.crushed {
            k * self.spec.crushed_stiffness_factor
        } else {
            k
        })
    }
}
