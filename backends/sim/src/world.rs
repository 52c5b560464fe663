//! The simulated world: finger servos, cable-driven fingers, the scene object and the
//! contact on every pad, stepped in fixed increments of simulated time.
//!
//! One [`World`] is shared ([`SharedWorld`]) by the simulated hub, which renders each pad's
//! indentation when it triggers a capture, and the simulated servo bus, which commands the
//! motors and reads them back. Both advance it to the injected clock's time first, so a
//! virtual clock gives bit-for-bit repeatable runs. Per step: each motor moves under the
//! cable's load; each finger relaxes to equilibrium against its springs and its pads'
//! contact; then the object reacts (crush, trigger, bolt, slip) and events are logged.

use std::sync::{Arc, Mutex};

use glam::DVec3;

use gelgrip_controller::actuator::{MotorCommand, MotorModel, MotorReading};
use gelgrip_controller::layout::{HandLayout, Placement};

use crate::config::SensorFaults;
use crate::contact::{PadContact, PadGrid, height_map, pad_contact};
use crate::fault_storm::{FaultStorm, FaultTally, StormEvent};
use crate::finger::{FingerMechanics, PadFrame, PadLoad};
use crate::load::{LoadSpec, WeightPull};
use crate::markers::GelShear;
use crate::motor::Xm430Motor;
use crate::object::ObjectState;
use crate::scene::HeightMap;
use crate::scene_spec::SceneSpec;
use crate::shapes::rotation_from_rpy_deg;
use crate::traction::{ContactGrip, SlipTruth, Traction, share_load};
use crate::world_log::{EventKind, WorldEvent, WorldLog};

/// Simulation step, µs.
pub const STEP_US: u64 = 5000;
/// Gauss–Seidel sweeps of the finger equilibrium per step.
const SWEEPS: usize = 2;
/// Standard gravity, m/s².
const G_M_PER_S2: f64 = 9.81;
/// Slip compliance: mm of slip per N of unbalanced load per step.
const SLIP_MM_PER_N: f64 = 0.05;
/// Fastest slip (and the speed of an object falling free of the hand), mm/s.
const SLIP_MAX_MM_PER_S: f64 = 500.0;

/// Where a sensor's pad is mounted.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mount {
    /// Fixed to the palm.
    Palm(PadFrame),
    /// On phalanx `phalanx` of finger `finger`.
    Finger { finger: usize, phalanx: usize },
    /// A generic sensor with no place on the hand: never touched.
    Nowhere,
}

/// A world shared by the simulated hub and servo bus.
pub type SharedWorld = Arc<Mutex<World>>;

/// The simulated world.
#[derive(Debug, Clone)]
pub struct World {
    mounts: Vec<Mount>,
    /// Per finger, per phalanx: the sensor on it.
    finger_pads: Vec<Vec<Option<usize>>>,
    grids: Vec<PadGrid>,
    fingers: Vec<FingerMechanics>,
    motors: Vec<Xm430Motor>,
    commands: Vec<MotorCommand>,
    /// Commands written ahead of the world's time: (host time µs, finger, command), in
    /// the order written; each takes effect from the step in which its time falls.
    pending: Vec<(u64, usize, MotorCommand)>,
    readings: Vec<MotorReading>,
    object: Option<ObjectState>,
    scene: Option<SceneSpec>,
    contacts: Vec<PadContact>,
    t_us: Option<u64>,
    elapsed_us: u64,
    log: WorldLog,
    /// Set by [`World::load_test`]: the object is let go and pulled by a rising multiple
    /// of its weight.
    weight_pull: Option<WeightPull>,
    /// Faults injected at run time per sensor (the dashboard's sim controls); they replace
    /// the configured ones.
    injected_faults: Vec<Option<SensorFaults>>,
    /// The hub is unplugged until this host time, µs (fault injection).
    hub_unplugged_until_us: Option<u64>,
    /// When the scene was set (its fixture's release time counts from here), µs of
    /// simulated time.
    scene_since_us: u64,
    /// The virtual-clock soak's storm of faults, applied at every trigger.
    fault_storm: Option<FaultStorm>,
    /// Per sensor, its contact's tangential state.
    traction: Vec<Traction>,
    /// Per sensor, how its gel's surface moves under that load (`None`: it does not).
    shear: Vec<Option<GelShear>>,
    /// When the held object began to slip under its load.
    slip_truth: SlipTruth,
}

fn palm_frame(xyz_mm: [f64; 3], rpy_deg: [f64; 3]) -> PadFrame {
    let r = rotation_from_rpy_deg(rpy_deg);
    PadFrame {
        center: DVec3::from_array(xyz_mm),
        normal: r * DVec3::Z,
        ex: r * DVec3::X,
        ey: r * DVec3::Y,
    }
}

impl World {
    /// The world of `layout`, with `scene` (or empty space) and the motors at 0°.
    pub fn new(layout: &HandLayout, scene: Option<SceneSpec>) -> Self {
        let mounts: Vec<Mount> = (0..layout.sensors.len())
            .map(|i| {
                match (
                    layout.sensors[i].id.placement(),
                    layout.phalanx_of_sensor(i),
                ) {
                    (Placement::Palm, _) => {
                        let pose = layout.sensors[i].pose;
                        Mount::Palm(palm_frame(pose.xyz_mm, pose.rpy_deg))
                    }
                    (_, Some((finger, phalanx))) => Mount::Finger { finger, phalanx },
                    _ => Mount::Nowhere,
                }
            })
            .collect();
        let grids = layout
            .sensors
            .iter()
            .map(|s| PadGrid {
                width_px: s.resolution.width_px as usize,
                height_px: s.resolution.height_px as usize,
                mm_per_px: s.mm_per_px,
            })
            .collect();
        let n = layout.fingers.len();
        let object = scene
            .as_ref()
            .map(|s| ObjectState::new(s.object.clone(), s.slip_dir));
        let finger_pads = layout
            .fingers
            .iter()
            .enumerate()
            .map(|(f, spec)| {
                (0..spec.phalanges.len())
                    .map(|phalanx| {
                        mounts
                            .iter()
                            .position(|m| *m == Mount::Finger { finger: f, phalanx })
                    })
                    .collect()
            })
            .collect();
        Self {
            finger_pads,
            contacts: vec![PadContact::default(); mounts.len()],
            traction: vec![Traction::default(); mounts.len()],
            shear: vec![None; mounts.len()],
            log: WorldLog::new(mounts.len()),
            mounts,
            grids,
            fingers: layout
                .fingers
                .iter()
                .cloned()
                .map(FingerMechanics::new)
                .collect(),
            motors: vec![Xm430Motor::default(); n],
            commands: vec![MotorCommand::default(); n],
            pending: Vec::new(),
            readings: vec![MotorReading::default(); n],
            object,
            scene,
            t_us: None,
            elapsed_us: 0,
            weight_pull: None,
            injected_faults: Vec::new(),
            hub_unplugged_until_us: None,
            scene_since_us: 0,
            fault_storm: None,
            slip_truth: SlipTruth::default(),
        }
    }

    /// Replace the scene with `scene` (`None`: empty space): the new object starts at its
    /// place, at rest, its fixture's release time counts from now, the event log starts
    /// afresh, and every pad is untouched until the next step. The fingers and motors stay
    /// where they are, so switch with the fingers open.
    pub fn set_scene(&mut self, scene: Option<SceneSpec>) {
        self.scene_since_us = self.elapsed_us;
        self.log = WorldLog::new(self.mounts.len());
        self.object = scene
            .as_ref()
            .map(|s| ObjectState::new(s.object.clone(), s.slip_dir));
        self.scene = scene;
        self.weight_pull = None;
        for c in &mut self.contacts {
            *c = PadContact::default();
        }
        self.traction.fill(Traction::default());
        self.shear.fill(None);
        self.slip_truth = SlipTruth::default();
    }

    /// How sensor `sensor`'s gel surface moves under its contact's tangential load now
    /// (`None`: no load, or no such sensor).
    pub fn gel_shear(&self, sensor: usize) -> Option<GelShear> {
        self.shear.get(sensor).copied().flatten()
    }

    /// A contact's tangential state now (`None`: no such sensor).
    pub fn traction(&self, sensor: usize) -> Option<&Traction> {
        self.traction.get(sensor)
    }

    /// Sensor `sensor`'s true stick ratio now: its contact's under a tangential load, 1
    /// without a contact or a load (and for no such sensor).
    pub fn stick_ratio(&self, sensor: usize) -> f64 {
        self.traction(sensor)
            .filter(|t| t.contact_radius_mm > 0.0 && t.tangential_n > 0.0)
            .map_or(1.0, |t| t.stick_ratio)
    }

    /// When the held object began to slip under its load, and how far it has moved.
    pub fn slip_truth(&self) -> &SlipTruth {
        &self.slip_truth
    }

    /// Inject `faults` into sensor `sensor` from now on (replacing the configured ones);
    /// `None` goes back to the configuration.
    pub fn inject_faults(&mut self, sensor: usize, faults: Option<SensorFaults>) {
        if self.injected_faults.len() <= sensor {
            self.injected_faults.resize(sensor + 1, None);
        }
        self.injected_faults[sensor] = faults;
    }

    /// The faults injected into sensor `sensor`, if any.
    pub fn injected_faults(&self, sensor: usize) -> Option<&SensorFaults> {
        self.injected_faults.get(sensor)?.as_ref()
    }

    /// Unplug the simulated hub until host time `until_us`: every trigger fired before then
    /// reaches no board (each is reported disconnected), as on a bridge with no set buffer.
    pub fn unplug_hub(&mut self, until_us: u64) {
        self.hub_unplugged_until_us = Some(until_us);
    }

    /// Whether the hub is unplugged at host time `at_us`.
    pub fn hub_unplugged(&self, at_us: u64) -> bool {
        self.hub_unplugged_until_us
            .is_some_and(|until| at_us < until)
    }

    /// Let `storm` inject its faults from now on (`None`: stop it; faults it opened stay
    /// until replaced).
    pub fn set_fault_storm(&mut self, storm: Option<FaultStorm>) {
        self.fault_storm = storm;
    }

    /// Apply the storm's episodes due by host time `now_us` (the hub calls it at each
    /// trigger).
    pub fn apply_fault_storm(&mut self, now_us: u64) {
        let Some(events) = self.fault_storm.as_mut().map(|s| s.due(now_us)) else {
            return;
        };
        for event in events {
            match event {
                StormEvent::Sensor { sensor, faults, .. } => {
                    self.inject_faults(sensor, Some(faults));
                }
                StormEvent::SensorEnd { sensor } => self.inject_faults(sensor, None),
                StormEvent::Unplug { until_us } => self.unplug_hub(until_us),
                StormEvent::ServoOverload { finger } => {
                    self.change_motor(finger, Xm430Motor::overloaded);
                }
                StormEvent::HttpBurst => {}
            }
        }
    }

    /// Count frames the hub corrupted and dropped (while a storm runs).
    pub fn count_faulted_frames(&mut self, corrupted: u64, dropped: u64) {
        if let Some(s) = self.fault_storm.as_mut() {
            s.count_frames(corrupted, dropped);
        }
    }

    /// The storm's events so far (`None`: no storm).
    pub fn fault_tally(&self) -> Option<FaultTally> {
        self.fault_storm.as_ref().map(FaultStorm::tally)
    }

    /// Take the storm's HTTP bursts due since the last call.
    pub fn take_http_bursts(&mut self) -> u64 {
        self.fault_storm.as_mut().map_or(0, FaultStorm::take_bursts)
    }

    /// Number of sensors.
    pub fn sensors(&self) -> usize {
        self.mounts.len()
    }

    /// Share it between the hub and the servo bus.
    pub fn into_shared(self) -> SharedWorld {
        Arc::new(Mutex::new(self))
    }

    /// Number of fingers (servos).
    pub fn fingers(&self) -> usize {
        self.fingers.len()
    }

    /// The scene, if any.
    pub fn scene(&self) -> Option<&SceneSpec> {
        self.scene.as_ref()
    }

    /// The object now, if the scene has one.
    pub fn object(&self) -> Option<&ObjectState> {
        self.object.as_ref()
    }

    /// What happened so far.
    pub fn log(&self) -> &WorldLog {
        &self.log
    }

    /// Simulated time since the first advance, s.
    pub fn elapsed_s(&self) -> f64 {
        self.elapsed_us as f64 / 1e6
    }

    /// Let go of the object and pull it along gravity with `factor` times its weight,
    /// reached over `rise_s` from what it carries now (the hold test: a grasp holds when
    /// the object slips less than 1 mm under twice its weight; a lift: once its weight).
    pub fn load_test(&mut self, factor: f64, rise_s: f64) {
        let now = match &self.weight_pull {
            Some(p) => p.last_factor(),
            None if self.log.has(EventKind::Released) => 1.0,
            None => 0.0,
        };
        self.weight_pull = Some(WeightPull::new(now, factor, rise_s));
    }

    /// Command every finger to close fully, its current capped at `current_ma`.
    pub fn close_fingers(&mut self, current_ma: f64) {
        for f in 0..self.fingers.len() {
            self.set_command(
                f,
                MotorCommand {
                    torque_on: true,
                    goal_position_deg: 180.0,
                    goal_current_ma: current_ma,
                    profile_velocity_rpm: 0.0,
                },
            );
        }
    }

    /// Command finger `finger`'s motor.
    pub fn set_command(&mut self, finger: usize, command: MotorCommand) {
        if let Some(c) = self.commands.get_mut(finger) {
            *c = command;
        }
    }

    /// Command finger `finger`'s motor from host time `at_us` on, without stepping the world
    /// there now: the command takes effect from the step in which `at_us` falls, exactly as
    /// [`World::advance_to`]`(at_us)` followed by [`World::set_command`] would, but the
    /// stepping is left to whoever next advances the world (so a servo write costs no
    /// physics).
    pub fn command_at(&mut self, finger: usize, command: MotorCommand, at_us: u64) {
        match self.t_us {
            Some(origin) if at_us >= origin + self.elapsed_us + STEP_US => {
                self.pending.push((at_us, finger, command));
            }
            _ => self.set_command(finger, command),
        }
    }

    /// The motor command of `finger`.
    pub fn command(&self, finger: usize) -> Option<MotorCommand> {
        self.commands.get(finger).copied()
    }

    /// The last motor reading of `finger`.
    pub fn reading(&self, finger: usize) -> Option<MotorReading> {
        self.readings.get(finger).copied()
    }

    /// Replace `finger`'s motor (fault injection: a hot or worn motor).
    pub fn set_motor(&mut self, finger: usize, motor: Xm430Motor) {
        if let Some(m) = self.motors.get_mut(finger) {
            *m = motor;
        }
    }

    /// Replace `finger`'s motor by `change` of it (fault injection: a servo that overloads
    /// or overheats now).
    pub fn change_motor(&mut self, finger: usize, change: impl FnOnce(Xm430Motor) -> Xm430Motor) {
        if let Some(m) = self.motors.get_mut(finger) {
            *m = change(m.clone());
        }
    }

    /// Clear `finger`'s motor faults (a servo reboot).
    pub fn reboot_motor(&mut self, finger: usize) {
        let Some(m) = self.motors.get_mut(finger) else {
            return;
        };
        m.reboot();
        let faults = m.faults();
        if let Some(r) = self.readings.get_mut(finger) {
            r.hardware_error = faults;
        }
    }

    /// Joint flexions of `finger`, rad.
    pub fn joints_rad(&self, finger: usize) -> Option<&[f64]> {
        self.fingers.get(finger).map(FingerMechanics::joints_rad)
    }

    /// The latest contact on sensor `sensor`.
    pub fn contact(&self, sensor: usize) -> Option<&PadContact> {
        self.contacts.get(sensor)
    }

    /// Where sensor `sensor`'s pad is now.
    pub fn pad_frame(&self, sensor: usize) -> Option<PadFrame> {
        match *self.mounts.get(sensor)? {
            Mount::Palm(frame) => Some(frame),
            Mount::Finger { finger, phalanx } => self.fingers.get(finger)?.pad(phalanx),
            Mount::Nowhere => None,
        }
    }

    /// The full-resolution gel indentation of `sensor`, or `None` when nothing touches it.
    pub fn height_map(&self, sensor: usize) -> Option<HeightMap> {
        let contact = self.contacts.get(sensor)?;
        contact.bbox_px?;
        let object = self.object.as_ref()?;
        let frame = self.pad_frame(sensor)?;
        Some(height_map(&frame, &self.grids[sensor], object, contact))
    }

    /// Step the world up to host time `now_us` (the first call only sets the origin).
    pub fn advance_to(&mut self, now_us: u64) {
        let origin = *self.t_us.get_or_insert(now_us);
        while origin + self.elapsed_us + STEP_US <= now_us {
            // Pending commands are in time order (host time only moves forward).
            let step_end_us = origin + self.elapsed_us + STEP_US;
            let due = self
                .pending
                .iter()
                .take_while(|(t, _, _)| *t < step_end_us)
                .count();
            for (_, finger, command) in self.pending.drain(..due) {
                if let Some(c) = self.commands.get_mut(finger) {
                    *c = command;
                }
            }
            self.step(STEP_US as f64 / 1e6);
            self.elapsed_us += STEP_US;
        }
    }

    fn step(&mut self, dt_s: f64) {
        for f in 0..self.fingers.len() {
            let load = self.fingers[f].servo_load_nm();
            self.readings[f] = self.motors[f].step(&self.commands[f], load, dt_s);
        }
        let pads = &self.finger_pads;
        let object = self.object.as_ref();
        let grids = &self.grids;
        for (f, finger) in self.fingers.iter_mut().enumerate() {
            let cable = finger.cable_mm(self.readings[f].position_deg);
            let mut contact = |phalanx: usize, frame: &PadFrame| -> PadLoad {
                match (object, pads[f].get(phalanx).copied().flatten()) {
                    (Some(o), Some(s)) => pad_contact(frame, &grids[s], o).load,
                    _ => PadLoad::default(),
                }
            };
            finger.relax(cable, SWEEPS, &mut contact);
        }
        for s in 0..self.mounts.len() {
            let contact = match (self.object.as_ref(), self.pad_frame(s)) {
                (Some(o), Some(frame)) => pad_contact(&frame, &self.grids[s], o),
                _ => PadContact::default(),
            };
            self.contacts[s] = contact;
        }
        let t_s = self.elapsed_s();
        self.react(t_s, dt_s);
        self.log.observe(t_s, &self.contacts);
    }

    /// The object's response to the contacts: crushing, the trigger and bolt, slip.
    fn react(&mut self, t_s: f64, dt_s: f64) {
        let (Some(o), Some(scene)) = (self.object.as_mut(), self.scene.as_ref()) else {
            return;
        };
        if let (Some(limit), false) = (o.spec().crush_force_n, o.crushed) {
            let worst = self
                .contacts
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.load.force_n.total_cmp(&b.1.load.force_n));
            if let Some((s, c)) = worst.filter(|(_, c)| c.load.force_n > limit) {
                o.crushed = true;
                self.log.push(
                    WorldEvent::at(t_s, EventKind::Crushed)
                        .sensor(s)
                        .value(c.load.force_n),
                );
            }
        }
        let (tf, ta) = self.contacts.iter().fold((0.0, 0.0), |(f, a), c| {
            (f + c.trigger_force_n, a + c.trigger_area_mm2)
        });
        let was_on = o.switch_on;
        o.update_trigger(tf, ta);
        if o.switch_on != was_on {
            let kind = if o.switch_on {
                EventKind::TriggerOn
            } else {
                EventKind::TriggerOff
            };
            self.log.push(WorldEvent::at(t_s, kind).value(o.trigger_mm));
        }
        let was_tight = o.bolt_tight;
        let reaction_n = o.update_bolt(dt_s);
        if o.bolt_tight && !was_tight {
            self.log
                .push(WorldEvent::at(t_s, EventKind::BoltTight).value(o.bolt_torque_nm));
        }
        let since_scene_s = t_s - self.scene_since_us as f64 / 1e6;
        let released =
            self.weight_pull.is_some() || scene.release_after_s.is_some_and(|r| since_scene_s >= r);
        if released && !self.log.has(EventKind::Released) {
            self.log.push(WorldEvent::at(t_s, EventKind::Released));
        }
        let pull_n = o.spec().load.map_or(0.0, |l| l.force_at_n(since_scene_s));
        let gravity_n = if released {
            self.weight_pull.as_mut().map_or(1.0, |p| p.factor_at(t_s))
                * o.spec().mass_kg
                * G_M_PER_S2
                * scene.gravity_dir.dot(scene.slip_dir)
        } else {
            0.0
        };
        self.hold(t_s, dt_s, gravity_n + reaction_n + pull_n, released);
    }

    /// Each contact's grip on the object now, and the load its normals carry along
    /// `slip_dir` (N); `None` without an object.
    fn grips(&self) -> Option<(Vec<ContactGrip>, f64)> {
        let (o, scene) = (self.object.as_ref()?, self.scene.as_ref()?);
        let d = scene.slip_dir;
        let mut support = 0.0;
        let mut grips = Vec::with_capacity(self.contacts.len());
        for (s, c) in self.contacts.iter().enumerate() {
            let n = match self.mounts[s] {
                Mount::Palm(frame) => frame.normal,
                Mount::Finger { finger, phalanx } => self.fingers[finger]
                    .pad(phalanx)
                    .map_or(DVec3::ZERO, |p| p.normal),
                Mount::Nowhere => DVec3::ZERO,
            };
            let force_n = c.load.force_n.max(0.0);
            let along = n.dot(d);
            support += force_n * along;
            grips.push(ContactGrip {
                capacity_n: o.spec().friction * force_n * (1.0 - along * along).max(0.0).sqrt(),
                contact_radius_mm: (c.area_mm2.max(0.0) / std::f64::consts::PI).sqrt(),
            });
        }
        Some((grips, support))
    }

    /// The grip on the object now: what its contacts' friction can carry along `slip_dir`
    /// (μP, N), and what their normals push along it (N; positive along `slip_dir`). The
    /// pull it holds before the object slides is the first less the second. Zeros without
    /// an object.
    pub fn grip_loads_n(&self) -> (f64, f64) {
        self.grips().map_or((0.0, 0.0), |(grips, push)| {
            let friction: f64 = grips.iter().map(|g| g.capacity_n).sum();
            let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
            (finite(friction).max(0.0), finite(push))
        })
    }

    /// The total normal force of the contacts on the object now, N.
    pub fn grip_n(&self) -> f64 {
        self.contacts.iter().map(|c| c.load.force_n.max(0.0)).sum()
    }

    /// The total normal force of the contacts on the palm's sensors now, N: a grip the
    /// fingers do not set (an object placed on the palm presses it however they grip).
    pub fn palm_grip_n(&self) -> f64 {
        self.contacts
            .iter()
            .zip(&self.mounts)
            .filter(|(_, m)| matches!(m, Mount::Palm(_)))
            .map(|(c, _)| c.load.force_n.max(0.0))
            .sum()
    }

    /// Replace the held object's tangential load (`[object.load]`; its `start_s` counts
    /// from the scene's start). Nothing without an object.
    pub fn set_object_load(&mut self, load: Option<LoadSpec>) {
        if let Some(o) = self.object.as_mut() {
            o.set_load(load);
        }
    }

    /// The object held against `load_n` along `slip_dir` by the contacts' normals and
    /// friction: each contact's traction, and the slip when friction cannot hold it.
    fn hold(&mut self, t_s: f64, dt_s: f64, load_n: f64, released: bool) {
        if load_n == 0.0 || self.object.as_ref().is_none_or(|o| o.dropped) {
            self.log.slipping = false;
            self.traction.fill(Traction::default());
            self.shear.fill(None);
            return;
        }
        let frames: Vec<Option<PadFrame>> =
            (0..self.mounts.len()).map(|s| self.pad_frame(s)).collect();
        let Some((grips, support)) = self.grips() else {
            return;
        };
        let (Some(o), Some(scene)) = (self.object.as_mut(), self.scene.as_ref()) else {
            return;
        };
        let d = scene.slip_dir;
        let friction: f64 = grips.iter().map(|g| g.capacity_n).sum();
        let net = load_n + support;
        let (shares, _) = share_load(net, &grips);
        for (((t, c), g), q) in self
            .traction
            .iter_mut()
            .zip(&self.contacts)
            .zip(&grips)
            .zip(shares)
        {
            *t = Traction::new(c.load.force_n, q, g.capacity_n, g.contact_radius_mm);
        }
        let shears = self
            .traction
            .iter()
            .zip(&self.contacts)
            .zip(&frames)
            .zip(&self.grids);
        for (shear, (((t, c), frame), grid)) in self.shear.iter_mut().zip(shears) {
            *shear = frame.and_then(|f| gel_shear(&f, grid, c.load.point, net.signum() * d, *t));
        }
        let touching = self.contacts.iter().any(|c| c.load.force_n > 0.0);
        if net.abs() > friction {
            let slip = if touching {
                ((net.abs() - friction) * SLIP_MM_PER_N).min(SLIP_MAX_MM_PER_S * dt_s)
            } else {
                SLIP_MAX_MM_PER_S * dt_s
            };
            o.slip_mm += slip * net.signum();
            if !self.log.slipping {
                self.log
                    .push(WorldEvent::at(t_s, EventKind::SlipStarted).value(o.slip_mm));
            }
            self.log.slipping = true;
        } else {
            self.log.slipping = false;
        }
        self.slip_truth.observe(t_s, o.slip_mm, &self.traction);
        if released && !touching && o.slip_mm.abs() > o.radius_mm() + 20.0 {
            o.dropped = true;
            self.log
                .push(WorldEvent::at(t_s, EventKind::Dropped).value(o.slip_mm));
        }
    }
}

/// How a pad's gel moves under `traction` whose load on the object is along `load_dir`
/// (gripper frame), its contact's centre of pressure at `point`: `None` when it carries no
/// load or the load has no component along the pad.
fn gel_shear(
    frame: &PadFrame,
    grid: &PadGrid,
    point: DVec3,
    load_dir: DVec3,
    traction: Traction,
) -> Option<GelShear> {
    let (dx, dy) = (load_dir.dot(frame.ex), load_dir.dot(frame.ey));
    let along = dx.hypot(dy);
    if !(traction.shift_mm > 0.0 && along > 1e-6 && grid.mm_per_px > 0.0) {
        return None;
    }
    let at = point - frame.center;
    Some(GelShear {
        centre_px: (
            grid.width_px as f64 / 2.0 + at.dot(frame.ex) / grid.mm_per_px,
            grid.height_px as f64 / 2.0 + at.dot(frame.ey) / grid.mm_per_px,
        ),
        direction: (dx / along, dy / along),
        traction,
    })
}
