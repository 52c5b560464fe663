//! The signals a task script's conditions test, read from fused sets: per source (a
//! sensor, a finger or the palm) its contact, depth, force, area and deformation signal,
//! with a short history for slopes and the values at the stage's start for changes.

use std::collections::VecDeque;

use crate::fusion::FusedSet;
use crate::layout::{HandLayout, Placement};

use super::script::{Condition, MAX_WINDOW_S, Source, Test};

/// One source's signals in one set (`None`: a reading is missing, so nothing is known).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SourceSignals {
    /// In contact.
    pub contact: bool,
    /// Deepest indentation, mm.
    pub depth_mm: f64,
    /// Force, N.
    pub force_n: f64,
    /// Contact area, mm².
    pub area_mm2: f64,
    /// Deformation signal (indentation volume), mm³.
    pub deformation_mm3: f64,
    /// The settled force of the source's finger's `auto` grasp, less and plus the grasp's
    /// stable band, N (`None`: a palm, a fixed target, or no force found yet).
    pub settled_range_n: Option<(f64, f64)>,
}

/// Which sensors make up each finger and the palm.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceMap {
    finger_sensors: Vec<Vec<usize>>,
    palm_sensors: Vec<usize>,
}

impl SourceMap {
    /// The map of `layout`.
    pub fn new(layout: &HandLayout) -> Self {
        let mut finger_sensors = vec![Vec::new(); layout.fingers.len()];
        let mut palm_sensors = Vec::new();
        for (s, spec) in layout.sensors.iter().enumerate() {
            if matches!(spec.id.placement(), Placement::Palm) {
                palm_sensors.push(s);
            } else if let Some((f, _)) = layout.phalanx_of_sensor(s) {
                finger_sensors[f].push(s);
            }
        }
        Self {
            finger_sensors,
            palm_sensors,
        }
    }

    /// The finger `source` belongs to (`None`: the palm, or a sensor on none).
    pub fn finger_of(&self, source: Source) -> Option<usize> {
        match source {
            Source::Finger(f) => Some(f),
            Source::Sensor(s) => self.finger_sensors.iter().position(|ss| ss.contains(&s)),
            Source::Palm => None,
        }
    }

    fn sensors_of(&self, source: Source) -> &[usize] {
        match source {
            Source::Sensor(_) => &[],
            Source::Finger(f) => self.finger_sensors.get(f).map_or(&[], Vec::as_slice),
            Source::Palm => &self.palm_sensors,
        }
    }

    /// `source`'s signals in `set`.
    pub fn read(&self, set: &FusedSet, source: Source) -> Option<SourceSignals> {
        let finite = |v: f64| if v.is_finite() { v.max(0.0) } else { 0.0 };
        let deformation = |sensors: &[usize]| -> Option<f64> {
            sensors
                .iter()
                .map(|s| set.deformation_mm3.get(*s).copied().flatten())
                .sum::<Option<f64>>()
        };
        match source {
            Source::Sensor(s) => {
                let r = set.sensors.get(s).copied().flatten()?;
                Some(SourceSignals {
                    contact: r.in_contact,
                    depth_mm: finite(r.max_depth_mm),
                    force_n: finite(r.force_n),
                    area_mm2: finite(r.area_mm2),
                    deformation_mm3: finite(r.volume_mm3),
                    settled_range_n: None,
                })
            }
            Source::Finger(_) | Source::Palm => {
                let fused = match source {
                    Source::Finger(f) => set.fingers.get(f).copied()?,
                    _ => set.palm?,
                };
                if fused.stale {
                    return None;
                }
                Some(SourceSignals {
                    contact: fused.contact,
                    depth_mm: finite(fused.max_depth_mm),
                    force_n: finite(fused.force_n),
                    area_mm2: finite(fused.area_mm2),
                    deformation_mm3: deformation(self.sensors_of(source))?,
                    settled_range_n: None,
                })
            }
        }
    }
}

/// Least-squares slope of `points` (t s, value), per second; `None` with fewer than three
/// points or no time span.
pub fn slope_per_s(points: &[(f64, f64)]) -> Option<f64> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mt, mv) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (t, v)| (a + t / n, b + v / n));
    let (num, den) = points.iter().fold((0.0, 0.0), |(num, den), (t, v)| {
        (num + (t - mt) * (v - mv), den + (t - mt) * (t - mt))
    });
    (den > 0.0 && num.is_finite()).then(|| num / den)
}

/// Sets whose median stands for "now" and for "the stage's start" in rise tests, so one
/// outlying set neither fakes nor hides a rise.
pub const RISE_MEDIAN_SETS: usize = 3;

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The recent past of every source a stage tests.
#[derive(Debug, Clone, Default)]
pub struct History {
    /// (time s, deformation per source) for the last [`MAX_WINDOW_S`].
    samples: VecDeque<(f64, Vec<Option<f64>>)>,
    /// The stage's first [`RISE_MEDIAN_SETS`] samples.
    first: Vec<Vec<Option<f64>>>,
}

impl History {
    /// Forget everything (a new stage).
    pub fn clear(&mut self) {
        self.samples.clear();
        self.first.clear();
    }

    /// How far source `k`'s deformation has risen since the stage's start, mm³: the median
    /// of the last few sets less the median of the first few (`None` until known).
    pub fn rise(&self, k: usize) -> Option<f64> {
        let pick = |v: &Vec<Option<f64>>| v.get(k).copied().flatten();
        let start = median(self.first.iter().filter_map(pick).collect())?;
        let recent: Vec<f64> = self
            .samples
            .iter()
            .rev()
            .take(RISE_MEDIAN_SETS)
            .filter_map(|(_, v)| pick(v))
            .collect();
        Some(median(recent)? - start)
    }

    /// Add the deformation of each of `sources` at `t_s`.
    pub fn push(&mut self, t_s: f64, values: Vec<Option<f64>>) {
        if self.first.len() < RISE_MEDIAN_SETS {
            self.first.push(values.clone());
        }
        self.samples.push_back((t_s, values));
        while self
            .samples
            .front()
            .is_some_and(|(t, _)| t_s - t > MAX_WINDOW_S)
        {
            self.samples.pop_front();
        }
    }

    /// Slope of source `k`'s deformation over the last `window_s`, mm³/s; `None` until the
    /// window holds three samples spanning half of it.
    pub fn slope(&self, k: usize, t_s: f64, window_s: f64) -> Option<f64> {
        let points: Vec<(f64, f64)> = self
            .samples
            .iter()
            .filter(|(t, _)| t_s - t <= window_s)
            .filter_map(|(t, v)| v.get(k).copied().flatten().map(|v| (*t, v)))
            .collect();
        let span = points.last()?.0 - points.first()?.0;
        if span < 0.5 * window_s {
            return None;
        }
        slope_per_s(&points)
    }
}

/// What a source's history adds to its signals now.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Trend {
    /// Deformation slope over the condition's window, mm³/s.
    pub slope: Option<f64>,
    /// Deformation rise since the stage's start, mm³.
    pub rise: Option<f64>,
}

/// Whether `test` passes for a source now (`now`), given its value at the stage's start
/// (`start`) and its trend.
pub fn passes(
    test: Test,
    now: &SourceSignals,
    start: Option<&SourceSignals>,
    trend: Trend,
) -> bool {
    let slope = trend.slope;
    match test {
        Test::Contact(v) => now.contact == v,
        Test::DepthMin(d) => now.depth_mm >= d,
        Test::ForceMin(f) => now.force_n >= f,
        Test::ForceMax(f) => now.force_n <= f,
        Test::ForceMinSettled => now.settled_range_n.is_some_and(|(lo, _)| now.force_n >= lo),
        Test::ForceMaxSettled => now.settled_range_n.is_some_and(|(_, hi)| now.force_n <= hi),
        Test::AreaChangePct(p) => start.is_some_and(|s| {
            let change = 100.0 * (now.area_mm2 - s.area_mm2) / s.area_mm2.max(1.0);
            if p > 0.0 { change >= p } else { change <= p }
        }),
        Test::RiseMin(r) => trend.rise.is_some_and(|rise| rise >= r),
        Test::SlopeMin(m) => slope.is_some_and(|s| s >= m),
        Test::SlopeMax(m) => slope.is_some_and(|s| s <= m),
    }
}

/// Whether `condition` holds in this set (ignoring its `for_s`): `now`, `start` and the
/// trends are per source of the condition, in order.
pub fn condition_holds(
    condition: &Condition,
    now: &[Option<SourceSignals>],
    start: &[Option<SourceSignals>],
    trends: &[Trend],
) -> bool {
    condition.sources.iter().enumerate().all(|(k, _)| {
        let Some(n) = now.get(k).copied().flatten() else {
            return false;
        };
        let s = start.get(k).and_then(Option::as_ref);
        let trend = trends.get(k).copied().unwrap_or_default();
        condition.tests.iter().all(|t| passes(*t, &n, s, trend))
    })
}
