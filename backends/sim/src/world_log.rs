//! What happened in the simulated world: events (first contact, crush, slip, drop, the
//! screwdriver's trigger and bolt), and per sensor the first contact time and peak force.
//! Runs report it; sensors are layout indices here and named by the caller.

use serde::Serialize;

use crate::contact::PadContact;

/// Kinds of world event.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A sensor touched the object for the first time.
    FirstContact,
    /// A contact force exceeded the object's crush force.
    Crushed,
    /// The fixture let go of the object.
    Released,
    /// The object began to slip in the grip.
    SlipStarted,
    /// The object left the hand.
    Dropped,
    /// The screwdriver's switch closed.
    TriggerOn,
    /// The screwdriver's switch opened.
    TriggerOff,
    /// The bolt reached the tool's clutch torque.
    BoltTight,
}

/// One event.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorldEvent {
    /// Simulated time, s.
    pub t_s: f64,
    /// What happened.
    pub kind: EventKind,
    /// The sensor involved (layout index).
    pub sensor: Option<usize>,
    /// A figure: force (N), slip (mm), trigger travel (mm) or torque (N·m).
    pub value: Option<f64>,
}

impl WorldEvent {
    /// An event of `kind` at `t_s`.
    pub fn at(t_s: f64, kind: EventKind) -> Self {
        Self {
            t_s,
            kind,
            sensor: None,
            value: None,
        }
    }

    /// With the sensor involved.
    pub fn sensor(mut self, sensor: usize) -> Self {
        self.sensor = Some(sensor);
        self
    }

    /// With its figure.
    pub fn value(mut self, value: f64) -> Self {
        self.value = Some(value);
        self
    }
}

/// The log.
#[derive(Debug, Clone, Default)]
pub struct WorldLog {
    events: Vec<WorldEvent>,
    first_contact_s: Vec<Option<f64>>,
    peak_force_n: Vec<f64>,
    /// The object is slipping now.
    pub(crate) slipping: bool,
}

/// Events kept at most (a long soak must not grow without bound).
const MAX_EVENTS: usize = 10_000;

impl WorldLog {
    /// An empty log for `sensors` sensors.
    pub fn new(sensors: usize) -> Self {
        Self {
            first_contact_s: vec![None; sensors],
            peak_force_n: vec![0.0; sensors],
            ..Self::default()
        }
    }

    /// Record an event.
    pub fn push(&mut self, event: WorldEvent) {
        if self.events.len() < MAX_EVENTS {
            self.events.push(event);
        }
    }

    /// Whether an event of `kind` happened.
    pub fn has(&self, kind: EventKind) -> bool {
        self.events.iter().any(|e| e.kind == kind)
    }

    /// Note the contacts after a step at `t_s`.
    pub fn observe(&mut self, t_s: f64, contacts: &[PadContact]) {
        for (s, c) in contacts.iter().enumerate() {
            if c.load.force_n <= 0.0 {
                continue;
            }
            if let Some(first) = self.first_contact_s.get_mut(s)
                && first.is_none()
            {
                *first = Some(t_s);
                if self.events.len() < MAX_EVENTS {
                    self.events
                        .push(WorldEvent::at(t_s, EventKind::FirstContact).sensor(s));
                }
            }
            if let Some(peak) = self.peak_force_n.get_mut(s) {
                *peak = peak.max(c.load.force_n);
            }
        }
    }

    /// Every event, in time order.
    pub fn events(&self) -> &[WorldEvent] {
        &self.events
    }

    /// When each sensor first touched, s.
    pub fn first_contact_s(&self) -> &[Option<f64>] {
        &self.first_contact_s
    }

    /// Peak normal force per sensor, N.
    pub fn peak_force_n(&self) -> &[f64] {
        &self.peak_force_n
    }
}
