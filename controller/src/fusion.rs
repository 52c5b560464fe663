//! Fusion of one gated set's per-sensor tactile readings into what the grasp controller
//! acts on: per finger (every sensor on that finger) and for the palm, contact presence,
//! area, deepest point, force and centroid; per sensor, the deformation signal (indentation
//! volume, the quantity the paper plots for the screwdriver task).
//!
//! A group's slip is told two ways: by the contact slipping most (the first sign of slip,
//! what is shown and reported) and by the contact slipping most among those that bear
//! their share of the force ([`SlipLoad`]: what the grip reflex holds by; a light touch
//! beside them is left out).
//!
//! A sensor whose reading is missing (its frame was corrupt or its pipeline failed) marks
//! its finger stale: the controller then holds that finger rather than guess.

use crate::layout::{HandLayout, Placement};

/// Standard gravity, m/s².
pub const STANDARD_GRAVITY_M_S2: f64 = 9.806_65;

/// The load of a weight of `grams` at rest, N (what a known weight presses a pad with, in
/// force calibration and in the emulator that plays it).
pub fn weight_force_n(grams: f64) -> f64 {
    grams / 1000.0 * STANDARD_GRAVITY_M_S2
}

/// What the sensing pipeline made of one sensor's frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorReading {
    /// Anything in contact.
    pub in_contact: bool,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Deepest indentation, mm.
    pub max_depth_mm: f64,
    /// Indentation volume, mm³ (the deformation signal).
    pub volume_mm3: f64,
    /// Force proxy, N (calibrated volume × stiffness).
    pub force_n: f64,
    /// Contact centroid on the pad, mm from the image centre (x right, y down).
    pub centroid_mm: Option<(f64, f64)>,
    /// The contact's slip as a marker gel shows it (`None`: unknown: a plain gel, or no
    /// marker dots under the contact; docs/slip.md).
    pub slip: Option<SensorSlip>,
}

/// What a contact's slip looks like.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, PartialOrd, Ord)]
pub enum SlipState {
    /// Sticking.
    #[default]
    None,
    /// Its rim slides, its centre sticks.
    Incipient,
    /// It slides.
    Gross,
}

impl SlipState {
    /// The report's name: `none`, `incipient` or `gross`.
    pub fn as_str(self) -> &'static str {
        match self {
            SlipState::None => "none",
            SlipState::Incipient => "incipient",
            SlipState::Gross => "gross",
        }
    }
}

/// One contact's slip, from the shear of its gel's marker dots.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorSlip {
    /// Mean shift of the dots inside the contact, `[x, y]` mm (image axes: x right, y down).
    pub shear_mm: [f64; 2],
    /// Estimated stick ratio c/a (1: all sticks).
    pub stick_ratio: f64,
    /// What that makes of the contact.
    pub state: SlipState,
}

/// The fused contact of one finger or of the palm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FusedContact {
    /// Any of its sensors in contact.
    pub contact: bool,
    /// Total contact area, mm².
    pub area_mm2: f64,
    /// Deepest indentation over its sensors, mm.
    pub max_depth_mm: f64,
    /// Total force proxy, N.
    pub force_n: f64,
    /// Force-weighted centroid on the sensor carrying most force: (sensor index, x mm, y mm).
    pub centroid: Option<(usize, f64, f64)>,
    /// One of its sensors had no reading in this set.
    pub stale: bool,
    /// The slip of its sensor slipping most (the most advanced state, then the least stick
    /// ratio); `None` when none of its sensors can tell.
    pub slip: Option<SensorSlip>,
    /// Its contacts' forces and slips, for the slip the grasp holds by ([`SlipLoad`]).
    pub slip_load: SlipLoad,
}

/// One set, fused.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FusedSet {
    /// Per finger, in the layout's `[[fingers]]` order.
    pub fingers: Vec<FusedContact>,
    /// The palm (if the layout has a palm sensor).
    pub palm: Option<FusedContact>,
    /// Per sensor, the deformation signal, mm³ (`None` when the reading is missing).
    pub deformation_mm3: Vec<Option<f64>>,
    /// Per sensor, its reading as the pipeline gave it (`None` when missing); task
    /// scripts' conditions on a named sensor read these.
    pub sensors: Vec<Option<SensorReading>>,
}

impl FusedSet {
    /// Total force over the fingers and the palm, N.
    pub fn total_force_n(&self) -> f64 {
        self.fingers.iter().map(|f| f.force_n).sum::<f64>() + self.palm.map_or(0.0, |p| p.force_n)
    }

    /// The fingers that `active` marks (by index; a finger past its end is left out) and
    /// the palm.
    fn taking_part<'a>(&'a self, active: &'a [bool]) -> impl Iterator<Item = &'a FusedContact> {
        self.fingers
            .iter()
            .zip(active)
            .filter(|(_, a)| **a)
            .map(|(f, _)| f)
            .chain(self.palm.as_ref())
    }

    /// [`FusedSet::slip`] over the fingers that `active` marks and the palm: a finger that
    /// another drive moves on purpose (a task's trigger) is left out.
    pub fn worst_slip(&self, active: &[bool]) -> Option<SensorSlip> {
        slipping_most(self.taking_part(active))
    }

    /// The slip a grasp holds by over the fingers that `active` marks and the palm: that of
    /// the contact slipping most among those bearing their share of the force
    /// ([`SlipLoad`]).
    pub fn held_slip(&self, active: &[bool]) -> Option<SensorSlip> {
        self.taking_part(active)
            .fold(SlipLoad::default(), |all, c| all.merged(&c.slip_load))
            .slip()
    }

    /// The grasp's slip: that of its finger (or palm) slipping most, as a finger's is that
    /// of its sensor slipping most (`None`: no contact's slip is known).
    pub fn slip(&self) -> Option<SensorSlip> {
        slipping_most(self.fingers.iter().chain(&self.palm))
    }
}

/// The slip of the one of `contacts` slipping most (`None` when none of them can tell).
fn slipping_most<'a>(contacts: impl Iterator<Item = &'a FusedContact>) -> Option<SensorSlip> {
    contacts.map(|c| c.slip).fold(None, worse_slip)
}

impl SensorSlip {
    /// The share of the contact's friction that its load uses: `1 − s³` for a stick ratio
    /// `s` (Cattaneo–Mindlin: `s = (1 − Q/μP)^(1/3)`), and all of it (1) once it slides or
    /// when its stick ratio is unreadable.
    pub fn grip_used(&self) -> f64 {
        if self.state == SlipState::Gross || !self.stick_ratio.is_finite() {
            return 1.0;
        }
        let s = self.stick_ratio.clamp(0.0, 1.0);
        1.0 - s * s * s
    }
}

/// How many contacts a [`SlipLoad`] keeps, the heaviest (the three-finger hand has seven
/// sensors).
pub const SLIP_LOAD_KEPT: usize = 8;

/// A contact whose force is below this share of the group's mean is light: its slip does
/// not stand for the group's.
pub const FAIR_SHARE: f64 = 0.5;

/// Contacts' slip as a grasp holds by it: that of the contact slipping most among those
/// that carry at least [`FAIR_SHARE`] of the mean force. Contacts share a load by
/// stiffness, each up to its own friction limit, so a light touch beside load-bearing
/// contacts reaches its limit first and reads sliding whole while the object holds (the
/// rubber duck's middle phalanx at 0.6 N beside tips at 3.4–3.9 N); it is left out. A
/// contact that bears its share and slides is the load sliding on it. Groups merge over
/// sensors, fingers and the palm.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SlipLoad {
    /// The force of the contacts whose slip is known, N.
    pub force_n: f64,
    /// How many contacts' slip is known.
    count: u32,
    /// The heaviest of them (force, N; slip), at most [`SLIP_LOAD_KEPT`].
    kept: [Option<(f64, SensorSlip)>; SLIP_LOAD_KEPT],
}

impl SlipLoad {
    /// How many contacts' slip is known.
    pub fn contacts(&self) -> u32 {
        self.count
    }

    /// Add a contact pressing with `force_n` and slipping as `slip`.
    pub fn add(&mut self, force_n: f64, slip: &SensorSlip) {
        let force_n = if force_n.is_finite() {
            force_n.max(0.0)
        } else {
            0.0
        };
        self.force_n += force_n;
        self.count += 1;
        self.keep(force_n, *slip);
    }

    /// Keep a contact: in a free place, or in place of the lightest kept when it is heavier.
    fn keep(&mut self, force_n: f64, slip: SensorSlip) {
        let place = self.kept.iter().position(Option::is_none).or_else(|| {
            let (k, lightest) = self
                .kept
                .iter()
                .enumerate()
                .filter_map(|(k, c)| c.map(|(f, _)| (k, f)))
                .min_by(|a, b| a.1.total_cmp(&b.1))?;
            (force_n > lightest).then_some(k)
        });
        if let Some(k) = place {
            self.kept[k] = Some((force_n, slip));
        }
    }

    /// Both groups' contacts together.
    pub fn merged(mut self, other: &SlipLoad) -> SlipLoad {
        self.force_n += other.force_n;
        self.count += other.count;
        for (f, slip) in other.kept.iter().flatten() {
            self.keep(*f, *slip);
        }
        self
    }

    /// The slip the group holds by (`None` without any contact whose slip is known): the
    /// slip of the contact slipping most among those pressing at least [`FAIR_SHARE`] of
    /// the mean force (all of them where no force is known).
    pub fn slip(&self) -> Option<SensorSlip> {
        let mean_n = self.force_n / f64::from(self.count.max(1));
        let floor_n = if mean_n.is_finite() {
            FAIR_SHARE * mean_n
        } else {
            0.0
        };
        self.kept
            .iter()
            .flatten()
            .filter(|(f, _)| *f >= floor_n)
            .map(|(_, slip)| Some(*slip))
            .fold(None, worse_slip)
    }
}

/// The one of `a` and `b` slipping most: the more advanced state, then the less stick.
pub fn worse_slip(a: Option<SensorSlip>, b: Option<SensorSlip>) -> Option<SensorSlip> {
    match (a, b) {
        (Some(x), Some(y)) => Some(if (y.state, -y.stick_ratio) > (x.state, -x.stick_ratio) {
            y
        } else {
            x
        }),
        (x, None) => x,
        (None, y) => y,
    }
}

/// Add one sensor to a finger's (or the palm's) accumulator; `best_n` is the largest force
/// of its sensors so far, whose centroid stands for the group.
fn add(acc: &mut FusedContact, best_n: &mut f64, sensor: usize, reading: Option<&SensorReading>) {
    let Some(r) = reading else {
        acc.stale = true;
        return;
    };
    let finite = |v: f64| if v.is_finite() { v.max(0.0) } else { 0.0 };
    let force = finite(r.force_n);
    acc.contact |= r.in_contact;
    acc.area_mm2 += finite(r.area_mm2);
    acc.max_depth_mm = acc.max_depth_mm.max(finite(r.max_depth_mm));
    acc.force_n += force;
    if let Some(slip) = r.slip.filter(|_| r.in_contact) {
        acc.slip = worse_slip(acc.slip, Some(slip));
        acc.slip_load.add(force, &slip);
    }
    if r.in_contact
        && (acc.centroid.is_none() || force > *best_n)
        && let Some((x, y)) = r
            .centroid_mm
            .filter(|(x, y)| x.is_finite() && y.is_finite())
    {
        acc.centroid = Some((sensor, x, y));
        *best_n = force;
    }
}

/// Fuse `readings` (one per sensor of `layout`, `None` where missing).
pub fn fuse(layout: &HandLayout, readings: &[Option<SensorReading>]) -> FusedSet {
    fuse_excluding(layout, readings, &[])
}

/// Fuse `readings`, where the sensors marked in `excluded` were left out of the set by the
/// gate: a finger carries on with its other sensors (an excluded one does not make it
/// stale), and holds only when every one of its sensors is excluded or missing.
pub fn fuse_excluding(
    layout: &HandLayout,
    readings: &[Option<SensorReading>],
    excluded: &[bool],
) -> FusedSet {
    let is_excluded = |s: usize| excluded.get(s).copied().unwrap_or(false);
    let mut set = FusedSet {
        fingers: vec![FusedContact::default(); layout.fingers.len()],
        palm: None,
        deformation_mm3: Vec::with_capacity(layout.sensors.len()),
        sensors: Vec::with_capacity(layout.sensors.len()),
    };
    let mut best = vec![0.0; layout.fingers.len()];
    let mut palm_best = 0.0;
    // Per finger (and the palm, last): sensors in the set.
    let mut in_set = vec![0usize; layout.fingers.len() + 1];
    for (s, spec) in layout.sensors.iter().enumerate() {
        let reading = readings.get(s).copied().flatten();
        let group = match spec.id.placement() {
            Placement::Palm => Some(layout.fingers.len()),
            Placement::Finger { .. } => layout.phalanx_of_sensor(s).map(|(f, _)| f),
            Placement::Generic(_) => None,
        };
        if is_excluded(s) {
            set.sensors.push(None);
            set.deformation_mm3.push(None);
            if group == Some(layout.fingers.len()) {
                set.palm.get_or_insert_with(FusedContact::default);
            }
            continue;
        }
        if let Some(g) = group {
            in_set[g] += 1;
        }
        set.sensors.push(reading);
        set.deformation_mm3.push(
            reading
                .map(|r| r.volume_mm3)
                .filter(|v| v.is_finite())
                .map(|v| v.max(0.0)),
        );
        match spec.id.placement() {
            Placement::Palm => add(
                set.palm.get_or_insert_with(FusedContact::default),
                &mut palm_best,
                s,
                reading.as_ref(),
            ),
            Placement::Finger { .. } => {
                if let Some((f, _)) = layout.phalanx_of_sensor(s) {
                    add(&mut set.fingers[f], &mut best[f], s, reading.as_ref());
                }
            }
            Placement::Generic(_) => {}
        }
    }
    // A finger (or the palm) with every sensor left out has nothing to act on: it holds.
    for (f, finger) in set.fingers.iter_mut().enumerate() {
        if in_set[f] == 0
            && (0..layout.sensors.len())
                .any(|s| layout.phalanx_of_sensor(s).is_some_and(|(g, _)| g == f))
        {
            finger.stale = true;
        }
    }
    if let Some(palm) = set.palm.as_mut()
        && in_set[layout.fingers.len()] == 0
    {
        palm.stale = true;
    }
    set
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout() -> HandLayout {
        HandLayout::from_toml(
            "three-finger.toml",
            include_str!("../../configs/layouts/three-finger.toml"),
        )
        .expect("layout")
    }

    fn touch(force_n: f64, x: f64) -> Option<SensorReading> {
        Some(SensorReading {
            in_contact: force_n > 0.0,
            area_mm2: force_n * 10.0,
            max_depth_mm: force_n * 0.1,
            volume_mm3: force_n * 12.5,
            force_n,
            centroid_mm: (force_n > 0.0).then_some((x, 0.0)),
            slip: None,
        })
    }

    #[test]
    fn fingers_sum_their_sensors_and_the_palm_stands_alone() {
        let l = layout();
        // Order: f1.middle, f1.tip, f2.middle, f2.tip, f3.middle, f3.tip, palm.
        let r = vec![
            touch(1.0, 1.0),
            touch(2.0, 2.0),
            touch(0.0, 0.0),
            touch(0.0, 0.0),
            touch(0.5, 3.0),
            touch(0.0, 0.0),
            touch(0.25, 4.0),
        ];
        let f = fuse(&l, &r);
        assert_eq!(f.fingers.len(), 3);
        assert!((f.fingers[0].force_n - 3.0).abs() < 1e-12);
        assert!((f.fingers[0].area_mm2 - 30.0).abs() < 1e-12);
        assert!((f.fingers[0].max_depth_mm - 0.2).abs() < 1e-12);
        assert_eq!(
            f.fingers[0].centroid,
            Some((1, 2.0, 0.0)),
            "the stronger sensor"
        );
        assert!(!f.fingers[1].contact && f.fingers[1].centroid.is_none());
        assert!(f.fingers[2].contact);
        assert_eq!(f.palm.map(|p| p.force_n), Some(0.25));
        assert!((f.total_force_n() - 3.75).abs() < 1e-12);
        assert_eq!(f.deformation_mm3[1], Some(25.0));
    }

    #[test]
    fn a_missing_reading_marks_its_finger_stale_and_nan_is_ignored() {
        let l = layout();
        let mut r = vec![touch(1.0, 0.0); 7];
        r[3] = None;
        r[4] = Some(SensorReading {
            force_n: f64::NAN,
            area_mm2: f64::INFINITY,
            ..SensorReading::default()
        });
        let f = fuse(&l, &r);
        assert!(f.fingers[1].stale && !f.fingers[0].stale);
        assert_eq!(f.deformation_mm3[3], None);
        assert!(
            f.fingers
                .iter()
                .all(|c| c.force_n.is_finite() && c.area_mm2.is_finite())
        );
    }

    #[test]
    fn a_finger_takes_the_slip_of_its_sensor_slipping_most_and_unknown_stays_unknown() {
        let layout = layout();
        let slip = |state, stick_ratio| SensorSlip {
            shear_mm: [0.1, 0.0],
            stick_ratio,
            state,
        };
        let mut r = vec![touch(1.0, 0.0); 7];
        let fused = fuse(&layout, &r);
        assert!(
            fused.fingers.iter().all(|f| f.slip.is_none()),
            "plain gels: unknown"
        );
        // Sensor `id`'s reading with `slip`.
        let set_slip = |r: &mut Vec<Option<SensorReading>>, id: &str, slip: SensorSlip| {
            let k = layout
                .sensors
                .iter()
                .position(|s| s.id.to_string() == id)
                .expect("a sensor of the layout");
            r[k] = r[k].map(|x| SensorReading {
                slip: Some(slip),
                ..x
            });
        };
        set_slip(&mut r, "f1.tip", slip(SlipState::None, 0.95));
        set_slip(&mut r, "f1.middle", slip(SlipState::Incipient, 0.7));
        let fused = fuse(&layout, &r);
        assert_eq!(fused.fingers[0].slip, Some(slip(SlipState::Incipient, 0.7)));
        assert!(fused.fingers[1..].iter().all(|f| f.slip.is_none()));
        // The grasp's: its finger (or palm) slipping most.
        assert_eq!(fused.slip(), Some(slip(SlipState::Incipient, 0.7)));
        set_slip(&mut r, "palm", slip(SlipState::Gross, 0.9));
        assert_eq!(fuse(&layout, &r).slip(), Some(slip(SlipState::Gross, 0.9)));
    }

    #[test]
    fn the_grip_used_follows_cattaneo_mindlin() {
        let slip = |stick_ratio, state| SensorSlip {
            shear_mm: [0.0, 0.0],
            stick_ratio,
            state,
        };
        assert_eq!(slip(1.0, SlipState::None).grip_used(), 0.0);
        // c/a = (1 − Q/μP)^(1/3) at Q/μP = 0.5.
        let s = 0.5f64.cbrt();
        assert!((slip(s, SlipState::Incipient).grip_used() - 0.5).abs() < 1e-12);
        assert_eq!(slip(0.8, SlipState::Gross).grip_used(), 1.0);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(slip(bad, SlipState::None).grip_used(), 1.0, "{bad}");
        }
        for out in [-1.0, 2.0] {
            let u = slip(out, SlipState::Incipient).grip_used();
            assert!((0.0..=1.0).contains(&u), "{out}: {u}");
        }
    }

    /// A contact slipping as `state` at `stick_ratio`, sheared `shear_mm` along x.
    fn slip_of(state: SlipState, stick_ratio: f64, shear_mm: f64) -> SensorSlip {
        SensorSlip {
            shear_mm: [shear_mm, 0.0],
            stick_ratio,
            state,
        }
    }

    #[test]
    fn a_light_contact_sliding_beside_load_bearing_ones_that_stick_does_not_slide_the_load() {
        // The rubber duck held after its table dropped (docs/control.md): a middle phalanx
        // at 0.6 N slides whole, the tips at 3.4–3.9 N stick at 0.9.
        let mut load = SlipLoad::default();
        load.add(0.6, &slip_of(SlipState::Gross, 0.18, 0.05));
        load.add(3.4, &slip_of(SlipState::None, 0.9, 0.12));
        load.add(3.9, &slip_of(SlipState::Incipient, 0.88, 0.15));
        assert_eq!(
            load.slip(),
            Some(slip_of(SlipState::Incipient, 0.88, 0.15)),
            "the load-bearing contact slipping most"
        );
        // When a load-bearing one slides, the load slides.
        let mut sliding = SlipLoad::default();
        sliding.add(0.6, &slip_of(SlipState::Gross, 0.18, 0.05));
        sliding.add(3.4, &slip_of(SlipState::Gross, 0.2, 0.3));
        sliding.add(3.9, &slip_of(SlipState::None, 0.95, 0.3));
        assert_eq!(sliding.slip().map(|s| s.state), Some(SlipState::Gross));
        // Three contacts alike, all creeping a little (the wet soap): the worst stands.
        let mut creep = SlipLoad::default();
        for (f, s) in [(0.3, 0.98), (0.32, 0.52), (0.29, 0.84)] {
            creep.add(f, &slip_of(SlipState::Incipient, s, 0.01));
        }
        assert_eq!(creep.slip().map(|s| s.stick_ratio), Some(0.52));
        // Merging adds the groups as if they were one: 6 contacts, 15.8 N, a mean of
        // 2.63 N; the 0.6 N contacts stay out.
        let merged = load.merged(&sliding);
        assert_eq!(merged.contacts(), 6);
        assert!((merged.force_n - 15.8).abs() < 1e-12);
        assert_eq!(merged.slip(), Some(slip_of(SlipState::Gross, 0.2, 0.3)));
    }

    #[test]
    fn a_slip_load_without_force_or_with_bad_values_stays_finite() {
        assert_eq!(SlipLoad::default().slip(), None);
        // No force known: every contact counts.
        let mut unforced = SlipLoad::default();
        unforced.add(0.0, &slip_of(SlipState::None, 1.0, 0.0));
        unforced.add(f64::NAN, &slip_of(SlipState::Gross, 0.1, 0.0));
        unforced.add(-3.0, &slip_of(SlipState::Incipient, 0.2, 0.0));
        assert_eq!(unforced.slip().map(|s| s.state), Some(SlipState::Gross));
        assert_eq!(unforced.force_n, 0.0);
        for bad in [f64::NAN, f64::INFINITY, -1.0, 1e300] {
            let mut l = SlipLoad::default();
            l.add(bad, &slip_of(SlipState::Incipient, bad, bad));
            l.add(1.0, &slip_of(SlipState::None, 0.9, 0.0));
            let s = l.slip().expect("known");
            assert!(l.force_n.is_finite(), "{bad}: {l:?}");
            assert!(
                s.state == SlipState::Incipient || s.stick_ratio == 0.9,
                "{bad}: {s:?}"
            );
        }
    }

    #[test]
    fn a_slip_load_keeps_the_heaviest_contacts() {
        let mut l = SlipLoad::default();
        // A sliding light contact first, then more heavier ones than it keeps.
        l.add(0.01, &slip_of(SlipState::Gross, 0.0, 0.0));
        for k in 0..SLIP_LOAD_KEPT {
            l.add(1.0 + k as f64, &slip_of(SlipState::None, 1.0, 0.0));
        }
        assert_eq!(l.contacts(), SLIP_LOAD_KEPT as u32 + 1);
        assert_eq!(l.slip().map(|s| s.state), Some(SlipState::None));
        l.add(20.0, &slip_of(SlipState::Incipient, 0.7, 0.0));
        assert_eq!(l.slip().map(|s| s.state), Some(SlipState::Incipient));
    }

    #[test]
    fn a_finger_sums_its_contacts_slip_load() {
        let l = layout();
        let mut r: Vec<Option<SensorReading>> = (0..7).map(|_| touch(1.0, 0.0)).collect();
        r[0] = touch(0.5, 0.0).map(|t| SensorReading {
            slip: Some(slip_of(SlipState::Gross, 0.1, 0.01)),
            ..t
        });
        r[1] = touch(3.0, 0.0).map(|t| SensorReading {
            slip: Some(slip_of(SlipState::None, 1.0, 0.02)),
            ..t
        });
        let f = fuse(&l, &r);
        let load = f.fingers[0].slip_load;
        assert_eq!(load.contacts(), 2);
        assert!((load.force_n - 3.5).abs() < 1e-12);
        assert_eq!(
            load.slip().map(|s| s.state),
            Some(SlipState::None),
            "0.5 N is light"
        );
        assert_eq!(f.fingers[0].slip.map(|s| s.state), Some(SlipState::Gross));
        assert_eq!(f.fingers[1].slip_load, SlipLoad::default());
    }

    #[test]
    fn a_grasp_reads_slip_over_the_fingers_taking_part_and_the_palm() {
        let l = layout();
        let with = |force_n: f64, slip: SensorSlip| {
            touch(force_n, 0.0).map(|t| SensorReading {
                slip: Some(slip),
                ..t
            })
        };
        // Order: f1.middle, f1.tip, f2.middle, f2.tip, f3.middle, f3.tip, palm.
        let mut r: Vec<Option<SensorReading>> = (0..7)
            .map(|_| with(2.0, slip_of(SlipState::None, 0.95, 0.01)))
            .collect();
        r[2] = with(2.0, slip_of(SlipState::Gross, 0.1, 0.3)); // f2, the trigger finger
        let f = fuse(&l, &r);
        let all = [true; 3];
        let trigger_out = [true, false, true];
        assert_eq!(f.worst_slip(&all), f.slip());
        assert_eq!(f.worst_slip(&all).map(|s| s.state), Some(SlipState::Gross));
        assert_eq!(
            f.worst_slip(&trigger_out).map(|s| s.state),
            Some(SlipState::None)
        );
        let held_all = f.held_slip(&all).expect("known");
        let held_out = f.held_slip(&trigger_out).expect("known");
        assert!(held_all.stick_ratio < held_out.stick_ratio, "{held_all:?}");
        assert!((held_out.stick_ratio - 0.95).abs() < 1e-9, "{held_out:?}");
        // The palm always counts; a mask shorter than the fingers leaves the rest out.
        r[6] = with(4.0, slip_of(SlipState::Gross, 0.0, 0.2));
        let f = fuse(&l, &r);
        assert_eq!(f.worst_slip(&[]).map(|s| s.state), Some(SlipState::Gross));
        assert_eq!(f.held_slip(&[]).map(|s| s.state), Some(SlipState::Gross));
        let none = FusedSet { palm: None, ..f };
        assert_eq!(none.worst_slip(&[]), None);
        assert_eq!(none.held_slip(&[]), None);
    }
}
