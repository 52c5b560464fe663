//! Report shapes printed by commands (`--json` fields from CONTRACTS.md) and their
//! human-readable forms.

use serde::Serialize;

use gelgrip_controller::gate::{ExcludedSensor, GateStats, ReasonCounts};
use gelgrip_controller::runtime::outcome::EndReason;

/// `run --json`.
#[derive(Debug, Serialize)]
pub struct RunReport {
    /// Sensor count.
    pub sensors: usize,
    /// Sets emitted.
    pub sets: u64,
    /// (sets − 1) / (t_last − t_first).
    pub set_rate_hz: f64,
    /// p99 capture spread, null without sets.
    pub spread_us_p99: Option<u64>,
    /// Faults during the run: the first 256 (`FAULTS_KEPT`) in full.
    pub faults: Vec<String>,
    /// Faults beyond those, counted (a long run under faults meets thousands).
    pub faults_omitted: u64,
    /// Frames dropped by reason.
    pub drops: ReasonCounts,
    /// Sets rejected by reason.
    pub sets_rejected: ReasonCounts,
    /// Why the run ended.
    pub end_reason: EndReason,
    /// Transport name.
    pub transport: String,
    /// Trigger mode.
    pub trigger: &'static str,
    /// `real` or `virtual`.
    pub clock: &'static str,
    /// Run time on that clock, s.
    pub elapsed_s: f64,
    /// Gate window in force, µs.
    pub max_spread_us: u32,
    /// Gate age limit in force, µs.
    pub max_age_us: u64,
    /// Median set latency (emission − earliest capture), ms.
    pub set_latency_ms_p50: Option<f64>,
    /// The bus model's latency for the layout (earliest capture to the set's last frame at
    /// the host), ms.
    pub bus_latency_ms: f64,
    /// The bus model's set period, ms.
    pub bus_set_period_ms: f64,
    /// The scene's object (a run on a scene).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub object: Option<String>,
    /// Whether the object was crushed (a run on a scene).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub crushed: Option<bool>,
    /// What happened in the scene.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scene: Option<gelgrip_sim::scene_report::SceneReport>,
    /// The servos' last states, in finger order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub servos: Option<Vec<gelgrip_controller::actuator::ServoState>>,
    /// The dashboard's URL (when it was served).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dashboard_url: Option<String>,
    /// The recorder's counters (`--record`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recording: Option<gelgrip_record::writer::RecorderStats>,
    /// The task fields (a task run).
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub task: Option<gelgrip_controller::runtime::task_report::TaskReport>,
    /// p99 set latency, ms.
    pub set_latency_ms_p99: Option<f64>,
    /// Frames (valid or corrupt) received.
    pub frames_received: u64,
    /// Gate policy `latest`: fusions of a frame already delivered in an earlier set (each
    /// frame counts once in the accounting); 0 under the other policies.
    pub frames_reused: u64,
    /// Frames delivered in emitted sets, each counted once (`7 × sets` while every sensor
    /// is in, fewer while the gate excludes some).
    pub frames_in_sets: u64,
    /// Sets delivered whose trigger sequence was not past the last set's (delivered twice,
    /// or out of order): 0 in a sound run.
    pub duplicate_sets: u64,
    /// Sensors left out of the sets at the end of the run because they kept failing the
    /// gate's window (the rest went on without them).
    pub excluded_sensors: Vec<ExcludedSensor>,
    /// Capture spread histogram: `[upper bound µs, sets]` in power-of-two buckets.
    pub spread_histogram_us: Vec<(u64, u64)>,
    /// What the sensors said of slip (none without a pilot), docs/slip.md.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slip: Option<gelgrip_controller::runtime::slip_tally::SlipTally>,
}

impl RunReport {
    /// Human-readable summary.
    pub fn to_text(&self) -> String {
        let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
        let mut s = format!(
            "gelgrip run: {} sensors on `{}` ({} trigger, {} clock), {:.1} s, ended: {}\n",
            self.sensors, self.transport, self.trigger, self.clock, self.elapsed_s, self.end_reason
        );
        s += &format!(
            "  sets {}  rate {:.1} Hz  spread p99 {} us  latency p50/p99 {}/{} ms\n",
            self.sets,
            self.set_rate_hz,
            self.spread_us_p99.map_or("-".into(), |v| v.to_string()),
            opt(self.set_latency_ms_p50),
            opt(self.set_latency_ms_p99),
        );
        s += &format!(
            "  gate window: spread <= {} us, age <= {:.1} ms\n",
            self.max_spread_us,
            self.max_age_us as f64 / 1e3
        );
        s += &format!("  frame drops   {}\n", counts_text(&self.drops));
        s += &format!("  sets rejected {}\n", counts_text(&self.sets_rejected));
        for f in &self.faults {
            s += &format!("  fault: {f}\n");
        }
        if self.faults_omitted > 0 {
            s += &format!(
                "  ({} more faults counted, not listed)\n",
                self.faults_omitted
            );
        }
        if let Some(servos) = &self.servos {
            let line: Vec<String> = servos
                .iter()
                .map(|v| {
                    format!(
                        "{:.1}° {:.0} mA {:.0} °C",
                        v.position_deg, v.current_ma, v.temperature_c
                    )
                })
                .collect();
            s += &format!("  servos: {}\n", line.join(" | "));
        }
        if let Some(scene) = &self.scene {
            s += &format!(
                "  scene {} ({}): touched {} (as expected: {}), crushed {}, dropped {}, slip {:.2} mm\n",
                scene.name,
                scene.object,
                scene.touched.join(", "),
                scene.contact_as_expected,
                scene.crushed,
                scene.dropped,
                scene.slip_mm
            );
        }
        if let Some(t) = &self.task {
            s += &format!(
                "  task {}: grasped {} ({}), peak {:.2} N for {}, stable after {} s, loop p99 {} ms\n",
                t.task,
                t.grasped,
                t.reason,
                t.peak_force_n,
                match (t.target_force_n, t.settled_force_n) {
                    (Some(target), _) => format!("a {target:.2} N target"),
                    (None, Some(settled)) => format!("an auto target, settled at {settled:.2} N"),
                    (None, None) => "an auto target".to_string(),
                },
                opt(t.time_to_stable_s),
                opt(t.loop_latency_ms_p99)
            );
        }
        s
    }
}

/// `late 0, incomplete 0, …`.
pub fn counts_text(c: &ReasonCounts) -> String {
    format!(
        "late {}, incomplete {}, out_of_window {}, corrupt {}, duplicate {}, disconnected {}, \
         superseded {}, excluded {}",
        c.late,
        c.incomplete,
        c.out_of_window,
        c.corrupt,
        c.duplicate,
        c.disconnected,
        c.superseded,
        c.excluded
    )
}

/// Latency quantile in ms.
pub fn latency_ms(stats: &GateStats, q: f64) -> Option<f64> {
    stats.latency_us_quantile(q).map(|us| us as f64 / 1e3)
}
