//! Replaying a recording (`gelgrip replay`, `record export`): its hub events go back
//! through the same gate (its policy and the limits the run used) and the emitted sets
//! through the tactile pipeline.
//!
//! With the recorded config (the default) or another one, the replay is checked against the
//! recording: the gate's decisions set by set, each sensor's fused reading (in contact,
//! area, depth, volume, force, and on a marker gel its slip) bit for bit wherever the run recorded one, and the grasp
//! API's control steps. With two configs it runs both pipelines on the same sets and
//! reports how their depth, contact area and force differ.

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use crate::error::{Context, Error};
use serde::Serialize;

use gelgrip_controller::acquire::{Acquisition, AcquisitionTap, make_gate};
use gelgrip_controller::actuator::FingerGoal;
use gelgrip_controller::clock::{Clock, RealClock, VirtualClock};
use gelgrip_controller::config::{AppConfig, GateSettings, Limit};
use gelgrip_controller::frame::FrameSet;
use gelgrip_controller::fusion::{FusedSet, SensorReading, fuse_excluding};
use gelgrip_controller::gate::SetDecision;
use gelgrip_controller::gripper::{GripperService, ServiceEvent};
use gelgrip_controller::hub::{HubError, HubEvent, HubTransport};
use gelgrip_record::format::{Meta, Record};
use gelgrip_record::reader::Recording;
use gelgrip_record::replay::{ReplayHub, Speed, prediction_for_limits};

use crate::wiring;
use gelgrip_plugins::sensing::Tactile;

/// How fast `replay` goes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ReplaySpeed {
    /// As fast as possible, on virtual time.
    Max,
    /// A factor of the recorded pace, on the real clock.
    Factor(f64),
}

/// Whose pipelines a replay runs.
#[derive(Debug, Clone, Copy)]
pub enum Pipelines<'a> {
    /// The recorded config's: the replay is checked against the recording.
    Recorded,
    /// Another config's (same sensors): checked against the recording too.
    Config(&'a Path),
    /// Two configs' on the same sets: how B's readings differ from A's.
    Compare(&'a Path, &'a Path),
}

fn open_pipelines(which: Pipelines<'_>, recorded: &AppConfig) -> crate::Result<Vec<Tactile>> {
    let registry = wiring::registry();
    let configs: Vec<AppConfig> = match which {
        Pipelines::Config(p) => vec![wiring::load_config(Some(p), &registry)?],
        Pipelines::Compare(a, b) => vec![
            wiring::load_config(Some(a), &registry)?,
            wiring::load_config(Some(b), &registry)?,
        ],
        Pipelines::Recorded => vec![recorded.clone()],
    };
    for c in &configs {
        if c.layout.sensors.len() != recorded.layout.sensors.len() {
            return Err(Error::Usage(crate::UsageError(format!(
                "{}: {} sensors, the recording {}",
                c.file,
                c.layout.sensors.len(),
                recorded.layout.sensors.len()
            ))));
        }
    }
    configs.iter().map(crate::tactile::open).collect()
}

/// The replayed gate's decisions (set, outcome) and the hub events counted.
pub type Seen = (Vec<(u32, &'static str)>, u64);

/// Collects the replayed gate's decisions, and counts the hub events.
struct Decisions(Arc<Mutex<Seen>>);

impl AcquisitionTap for Decisions {
    fn event(&mut self, _event: &HubEvent, _gate_host_us: u64) {
        if let Ok(mut d) = self.0.lock() {
            d.1 += 1;
        }
    }

    fn decision(&mut self, decision: &SetDecision, _host_us: u64) {
        if let (Some(seq), Ok(mut d)) = (decision.trigger_seq, self.0.lock()) {
            d.0.push((seq, decision.outcome.key()));
        }
    }
}

/// What the recording says the run decided and sensed.
#[derive(Default)]
struct Recorded {
    /// Records whose CRC failed (skipped).
    crc_errors: u64,
    decisions: Vec<(u32, String)>,
    /// Per set, each sensor's reading as compared ([`Compared`]).
    readings: HashMap<u32, Vec<Option<Compared>>>,
    /// Per set, the grasp-API service's commands and steps since the set before.
    controller: HashMap<u32, Vec<ServiceEvent>>,
}

/// A sensor's reading as the replay compares it, bit for bit: in contact, area, depth,
/// volume, force, then its slip: state (−1 unknown, 0 none, 1 incipient, 2 gross), stick
/// ratio and shear x, y (0 while unknown).
type Compared = [f64; 9];

fn as_array(r: &SensorReading) -> Compared {
    let slip = r.slip.map_or([-1.0, 0.0, 0.0, 0.0], |s| {
        [
            f64::from(s.state as u8),
            s.stick_ratio,
            s.shear_mm[0],
            s.shear_mm[1],
        ]
    });
    [
        f64::from(u8::from(r.in_contact)),
        r.area_mm2,
        r.max_depth_mm,
        r.volume_mm3,
        r.force_n,
        slip[0],
        slip[1],
        slip[2],
        slip[3],
    ]
}

/// A snapshot's sensor (`recording.md`'s `state` meta) as compared: a missing number is
/// NaN, which matches nothing.
fn snapshot_array(s: &serde_json::Value) -> Compared {
    let num = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let slip = &s["slip"];
    let state = match slip["state"].as_str() {
        None if slip.is_null() => -1.0,
        Some("none") => 0.0,
        Some("incipient") => 1.0,
        Some("gross") => 2.0,
        _ => f64::NAN,
    };
    let known = !slip.is_null();
    let or_zero = |v: &serde_json::Value| if known { num(v) } else { 0.0 };
    [
        f64::from(u8::from(s["in_contact"].as_bool().unwrap_or(false))),
        num(&s["area_mm2"]),
        num(&s["max_depth_mm"]),
        num(&s["volume_mm3"]),
        num(&s["force_n"]),
        state,
        or_zero(&slip["stick_ratio"]),
        or_zero(&slip["shear_mm"][0]),
        or_zero(&slip["shear_mm"][1]),
    ]
}

fn read_recorded(recording: &Recording) -> crate::Result<Recorded> {
    let mut out = Recorded::default();
    let summary = recording.scan(|r| match r {
        Record::Meta(Meta::Decision {
            trigger_seq,
            outcome,
            ..
        }) => out.decisions.push((trigger_seq, outcome)),
        Record::Meta(Meta::State { state, .. }) => {
            let seq = state["trigger_seq"].as_u64().map(|s| s as u32);
            if let (Some(seq), Ok(events)) = (
                seq,
                serde_json::from_value::<Vec<ServiceEvent>>(state["controller"].clone()),
            ) && !events.is_empty()
            {
                out.controller.insert(seq, events);
            }
            if let (Some(seq), Some(sensors)) = (seq, state["sensors"].as_array()) {
                let readings = sensors
                    .iter()
                    .map(|s| s.is_object().then(|| snapshot_array(s)))
                    .collect();
                out.readings.insert(seq, readings);
            }
        }
        _ => {}
    })?;
    out.crc_errors = summary.crc_errors;
    Ok(out)
}

/// Differences between two pipelines over the same sets.
#[derive(Debug, Default, Serialize)]
pub struct Difference {
    /// Sensor readings compared (both pipelines gave one).
    pub readings: u64,
    /// Mean and largest |A − B| of the deepest indentation, mm.
    pub depth_mae_mm: f64,
    /// Largest depth difference, mm.
    pub depth_max_abs_mm: f64,
    /// Mean |A − B| of the contact area, mm².
    pub area_mae_mm2: f64,
    /// Largest contact-area difference, mm².
    pub area_max_abs_mm2: f64,
    /// Mean and largest |A − B| of the force proxy, N.
    pub force_mae_n: f64,
    /// Largest force difference, N.
    pub force_max_abs_n: f64,
    /// Readings where one pipeline saw contact and the other did not.
    pub contact_disagreements: u64,
}

impl Difference {
    fn add(&mut self, a: &SensorReading, b: &SensorReading) {
        self.readings += 1;
        let one = |sum: &mut f64, max: &mut f64, d: f64| {
            *sum += d.abs();
            *max = max.max(d.abs());
        };
        one(
            &mut self.depth_mae_mm,
            &mut self.depth_max_abs_mm,
            a.max_depth_mm - b.max_depth_mm,
        );
        one(
            &mut self.area_mae_mm2,
            &mut self.area_max_abs_mm2,
            a.area_mm2 - b.area_mm2,
        );
        one(
            &mut self.force_mae_n,
            &mut self.force_max_abs_n,
            a.force_n - b.force_n,
        );
        if a.in_contact != b.in_contact {
            self.contact_disagreements += 1;
        }
    }

    fn finish(mut self) -> Self {
        let n = self.readings.max(1) as f64;
        self.depth_mae_mm /= n;
        self.area_mae_mm2 /= n;
        self.force_mae_n /= n;
        self
    }
}

/// The grasp-API service run again on the recorded commands and servo states, with the
/// replayed fused sets; its goals compared with the recorded ones bit for bit.
struct ControllerReplay {
    service: GripperService,
    compared: u64,
    mismatches: u64,
}

fn same_goals(a: &Option<Vec<FingerGoal>>, b: &Option<Vec<FingerGoal>>) -> bool {
    let bits = |g: &FingerGoal| {
        [
            g.position_deg.to_bits(),
            g.goal_current_ma.to_bits(),
            g.profile_velocity_rpm.to_bits(),
        ]
    };
    match (a, b) {
        (Some(a), Some(b)) => {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| bits(x) == bits(y))
        }
        (None, None) => true,
        _ => false,
    }
}

impl ControllerReplay {
    /// A service as the run built it for `config` (the task's, and the dashboard's).
    fn new(config: &AppConfig) -> Self {
        let (service, _handle) =
            GripperService::for_hand(&config.layout, config.servos.current_limit_ma, config.grasp);
        Self {
            service,
            compared: 0,
            mismatches: 0,
        }
    }

    fn replay(&mut self, events: &[ServiceEvent], fused: &FusedSet) {
        for event in events {
            match event {
                ServiceEvent::Applied { command } => {
                    self.service.replay(command);
                }
                ServiceEvent::Step {
                    t_s,
                    with_set,
                    servos,
                    goals,
                } => {
                    let got = self.service.step(*t_s, with_set.then_some(fused), servos);
                    self.compared += 1;
                    if !same_goals(&got, goals) {
                        self.mismatches += 1;
                    }
                }
            }
        }
    }
}

/// What a replay found (`gelgrip replay --json`).
#[derive(Debug, Serialize)]
pub struct ReplayReport {
    /// Sets the replayed gate emitted.
    pub sets: u64,
    /// Hub events replayed.
    pub events: u64,
    /// Recorded time replayed, s; and the wall time it took, s.
    pub duration_s: f64,
    /// The wall time the replay took, s.
    pub wall_s: f64,
    /// Gate decisions in the recording and in the replay, and the positions where they
    /// differ (set or outcome).
    pub decisions_recorded: usize,
    /// Gate decisions in the replay.
    pub decisions_replayed: usize,
    /// Positions where the decisions differ (set or outcome).
    pub decision_mismatches: usize,
    /// Sets whose fused readings the recording holds and the replay compared, and those
    /// whose readings differ in any bit (the recorded config or `--config`).
    pub fused_compared: u64,
    /// Sets whose readings differ in any bit.
    pub fused_mismatches: u64,
    /// Control steps the recording holds and the replay repeated (the recorded servo
    /// states and commands, the replayed fused set), and those whose goals differ in any
    /// bit (the recorded config or `--config`).
    pub controller_steps_compared: u64,
    /// Control steps whose goals differ in any bit.
    pub controller_mismatches: u64,
    /// `--compare A B`: how B's pipeline differs from A's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compare: Option<Difference>,
    /// Records skipped for a failed CRC.
    pub records_skipped: u64,
}

/// A recording's hub events through the gate the run used (its policy and limits).
pub struct ReplayedGate {
    acq: Acquisition,
    /// The replay's clock.
    pub clock: Arc<dyn Clock>,
    seen: Arc<Mutex<Seen>>,
}

impl ReplayedGate {
    /// Replay `recording` (whose config is `config`, gate limits as recorded) at `speed`.
    pub fn open(
        recording: &Recording,
        config: &AppConfig,
        speed: ReplaySpeed,
        max_spread_us: u32,
        max_age_us: u64,
    ) -> crate::Result<Self> {
        let (clock, speed): (Arc<dyn Clock>, Speed) = match speed {
            ReplaySpeed::Max => (VirtualClock::new(), Speed::Max),
            ReplaySpeed::Factor(f) => (Arc::new(RealClock::new()), Speed::Factor(f)),
        };
        let hub = ReplayHub::open(
            recording,
            speed,
            clock.clone(),
            config.hub.trigger,
            prediction_for_limits(max_spread_us, max_age_us),
        )?;
        let gate_settings = GateSettings {
            max_spread_us: Limit::Fixed(max_spread_us),
            max_age_us: Limit::Fixed(max_age_us),
            ..config.gate.clone()
        };
        let gate = make_gate(&gate_settings, &config.layout, &hub.describe().prediction);
        let seen = Arc::new(Mutex::new((Vec::new(), 0)));
        let acq = Acquisition::new(Box::new(hub), gate, clock.clone(), 0)
            .with_tap(Box::new(Decisions(seen.clone())));
        Ok(Self { acq, clock, seen })
    }

    /// The next set the gate emits; `None` at the end of the recording.
    pub async fn next_set(&mut self) -> crate::Result<Option<FrameSet>> {
        loop {
            match self.acq.step().await {
                Ok(Some(set)) => return Ok(Some(set)),
                Ok(None) => {}
                Err(HubError::Finished { .. }) => return Ok(None),
                Err(e) => return Err(e).context("replaying"),
            }
        }
    }

    /// The gate's statistics so far.
    pub fn stats(&self) -> &gelgrip_controller::gate::GateStats {
        self.acq.gate().stats()
    }

    /// The gate's decisions so far and the hub events replayed.
    pub fn seen(&self) -> Seen {
        self.seen.lock().map(|d| d.clone()).unwrap_or_default()
    }
}

/// What the exports read `recording` with: its config, its tactile pipelines and its gate
/// replayed as fast as it goes, with the limits it was recorded under.
pub fn replay_at_max(recording: &Recording) -> crate::Result<(AppConfig, Tactile, ReplayedGate)> {
    let (config, max_spread_us, max_age_us) = recorded_config(recording)?;
    let tactile = crate::tactile::open(&config)?;
    let replayed = ReplayedGate::open(
        recording,
        &config,
        ReplaySpeed::Max,
        max_spread_us,
        max_age_us,
    )?;
    Ok((config, tactile, replayed))
}

/// The recorded config (rebuilt from the files the recording carries) and the gate limits
/// the run used.
pub fn recorded_config(recording: &Recording) -> crate::Result<(AppConfig, u32, u64)> {
    let Meta::Header {
        config,
        max_spread_us,
        max_age_us,
        ..
    } = recording.header()?
    else {
        return Err(Error::Recording("the recording has no header".into()));
    };
    let files: Vec<(String, String)> =
        serde_json::from_str(&config).map_err(|source| Error::Json {
            what: "the recording's config files".into(),
            source,
        })?;
    let first = files
        .first()
        .map(|(p, _)| p.clone())
        .ok_or_else(|| Error::Recording("the recording holds no config file".into()))?;
    let registry = wiring::registry();
    let config = wiring::load_config_from_memory(Path::new(&first), files, &registry)
        .context("the recording's config")?;
    Ok((config, max_spread_us, max_age_us))
}

/// Replay the recording in `dir` at `speed` through its gate and `pipelines`' configs (the
/// recorded config, `--config`'s, or `--compare`'s two): with one, the replay is checked
/// against the recording bit for bit; with two, B's readings are compared with A's.
pub async fn replay(
    dir: &Path,
    speed: ReplaySpeed,
    pipelines: Pipelines<'_>,
) -> crate::Result<ReplayReport> {
    let recording = Recording::open(dir)?;
    let (config, max_spread_us, max_age_us) = recorded_config(&recording)?;
    let recorded = read_recorded(&recording)?;
    let comparing = matches!(pipelines, Pipelines::Compare(..));
    let mut tactiles = open_pipelines(pipelines, &config)?;
    let mut replayed = ReplayedGate::open(&recording, &config, speed, max_spread_us, max_age_us)?;
    let wall = Instant::now();
    let start_us = replayed.clock.now_us();
    let (mut sets, mut fused_compared, mut fused_mismatches) = (0u64, 0u64, 0u64);
    let mut difference = comparing.then(Difference::default);
    let mut controller = ControllerReplay::new(&config);
    loop {
        let Some(set) = replayed.next_set().await? else {
            break;
        };
        sets += 1;
        let readings: Vec<Vec<Option<SensorReading>>> =
            tactiles.iter_mut().map(|t| t.process(&set)).collect();
        if let Some(diff) = difference.as_mut() {
            for (a, b) in readings[0].iter().zip(&readings[1]) {
                if let (Some(a), Some(b)) = (a, b) {
                    diff.add(a, b);
                }
            }
        } else if let Some(events) = recorded.controller.get(&set.trigger_seq) {
            let left_out = set.left_out(config.layout.sensors.len());
            let fused = fuse_excluding(&config.layout, &readings[0], &left_out);
            controller.replay(events, &fused);
        }
        if difference.is_none()
            && let Some(expected) = recorded.readings.get(&set.trigger_seq)
        {
            fused_compared += 1;
            let got: Vec<Option<Compared>> = readings[0]
                .iter()
                .map(|r| r.as_ref().map(as_array))
                .collect();
            let same = got.len() == expected.len()
                && got.iter().zip(expected).all(|(g, e)| match (g, e) {
                    (Some(g), Some(e)) => g.iter().zip(e).all(|(a, b)| a.to_bits() == b.to_bits()),
                    (None, None) => true,
                    _ => false,
                });
            if !same {
                fused_mismatches += 1;
            }
        }
    }
    let (replayed_decisions, events) = replayed.seen();
    let decision_mismatches = recorded
        .decisions
        .iter()
        .zip(&replayed_decisions)
        .filter(|((s1, o1), (s2, o2))| s1 != s2 || o1 != o2)
        .count()
        + recorded.decisions.len().abs_diff(replayed_decisions.len());
    let report = ReplayReport {
        sets,
        events,
        duration_s: replayed.clock.now_us().saturating_sub(start_us) as f64 / 1e6,
        wall_s: wall.elapsed().as_secs_f64(),
        decisions_recorded: recorded.decisions.len(),
        decisions_replayed: replayed_decisions.len(),
        decision_mismatches,
        fused_compared,
        fused_mismatches,
        controller_steps_compared: controller.compared,
        controller_mismatches: controller.mismatches,
        compare: difference.map(Difference::finish),
        records_skipped: recorded.crc_errors,
    };
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;
    use gelgrip_controller::fusion::{SensorSlip, SlipState};
    use gelgrip_record::observer::SensorSnapshot;

    /// A reading written to a snapshot (as the recorder does) and read back compares equal
    /// to itself, bit for bit, its slip too; a changed slip does not.
    #[test]
    fn a_snapshot_reads_back_as_the_reading_with_its_slip() {
        let reading = SensorReading {
            in_contact: true,
            area_mm2: 12.345_678_9,
            max_depth_mm: 0.1 + 0.2,
            volume_mm3: 1.0 / 3.0,
            force_n: 0.987_654_321,
            centroid_mm: None,
            slip: Some(SensorSlip {
                shear_mm: [0.012_345, -1e-17],
                stick_ratio: 0.72,
                state: SlipState::Incipient,
            }),
        };
        let back = |r: &SensorReading| {
            let json = serde_json::to_value(SensorSnapshot::from(r)).expect("serialises");
            snapshot_array(&json)
        };
        let bits = |a: Compared| a.map(f64::to_bits);
        assert_eq!(bits(back(&reading)), bits(as_array(&reading)));
        let unknown = SensorReading {
            slip: None,
            ..reading
        };
        assert_eq!(bits(back(&unknown)), bits(as_array(&unknown)));
        assert_ne!(bits(back(&unknown)), bits(as_array(&reading)));
        let gross = SensorReading {
            slip: reading.slip.map(|s| SensorSlip {
                state: SlipState::Gross,
                ..s
            }),
            ..reading
        };
        assert_ne!(bits(back(&reading)), bits(as_array(&gross)));
    }
}
