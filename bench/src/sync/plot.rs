//! `bench sync --plot`: overshoot against delay, in panels stacked top to bottom. With
//! several objects or speeds, one panel per object and speed, one line per policy, gating
//! and fault; with one object at one speed, one panel per fault, one line per policy and
//! gating. Each panel is a [`crate::plot::Figure`] with its own y scale; several panels
//! are written as one SVG of nested `<svg>` elements (a PNG holds one panel).

use std::path::Path;

use anyhow::Context;

use super::{Fault, Policy, SyncRow};
use crate::plot::{Figure, Format, Series};

/// The size of a panel as `gelgrip::plot` draws it, px.
const PANEL_W: u32 = 1200;
const PANEL_H: u32 = 600;

/// What one line shares: policy, gating, fault, object and speed (bits).
type LineKey = (Policy, bool, Fault, String, u64);

fn line_key(r: &SyncRow) -> LineKey {
    (
        r.policy,
        r.gating,
        r.fault,
        r.object.clone(),
        r.speed_deg_s.to_bits(),
    )
}

fn distinct<T: PartialEq>(items: impl Iterator<Item = T>) -> Vec<T> {
    let mut out = Vec::new();
    for item in items {
        if !out.contains(&item) {
            out.push(item);
        }
    }
    out
}

/// `trigger, gating on`, `approximate`, `latest`: the policy, and the gating where the
/// policy has rows of both.
fn policy_label(policy: Policy, gating: bool) -> String {
    match policy {
        Policy::Trigger if gating => "trigger, gating on".into(),
        Policy::Trigger => "trigger, gating off".into(),
        other => other.to_string(),
    }
}

/// How the rows split into panels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Split {
    /// One panel per object and speed; lines by policy, gating and fault.
    ObjectSpeed,
    /// One panel per fault; lines by policy and gating.
    Fault,
}

/// The rows with a delay (drift rows have none), grouped into panels.
fn panels(rows: &[SyncRow]) -> (Split, Vec<Vec<&SyncRow>>) {
    let rows: Vec<&SyncRow> = rows.iter().filter(|r| r.drift_ppm.is_none()).collect();
    let object_speed = |r: &SyncRow| (r.object.clone(), r.speed_deg_s.to_bits());
    let split = if distinct(rows.iter().map(|r| object_speed(r))).len() > 1 {
        Split::ObjectSpeed
    } else {
        Split::Fault
    };
    let panel_key = |r: &SyncRow| match split {
        Split::ObjectSpeed => format!("{} {}", r.object, r.speed_deg_s),
        Split::Fault => r.fault.to_string(),
    };
    let groups = distinct(rows.iter().map(|r| panel_key(r)))
        .into_iter()
        .map(|key| {
            rows.iter()
                .copied()
                .filter(|r| panel_key(r) == key)
                .collect()
        })
        .collect();
    (split, groups)
}

/// The fault's words on an axis or a title.
fn fault_text(fault: Fault) -> &'static str {
    match fault {
        Fault::Capture => "capture skew",
        Fault::Delivery => "stale delivery",
        Fault::Jitter => "capture jitter (bound)",
        Fault::Drift => "clock drift",
    }
}

fn figure(split: Split, rows: &[&SyncRow], target_force_n: f64) -> Figure {
    let series = distinct(rows.iter().map(|r| line_key(r)))
        .into_iter()
        .map(|key| {
            let (policy, gating, fault, _, _) = &key;
            let mut name = policy_label(*policy, *gating);
            if split == Split::ObjectSpeed {
                name += &format!(", {}", fault_text(*fault));
            }
            let mut points: Vec<(f64, Option<f64>)> = rows
                .iter()
                .filter(|r| line_key(r) == key)
                .map(|r| (r.delay_ms, r.overshoot_pct))
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            if points.iter().all(|p| p.1.is_none()) {
                name += " (never squeezed)";
            }
            Series { name, points }
        })
        .collect();
    let first = rows[0];
    let sensors = distinct(rows.iter().map(|r| r.sensor.as_str())).join(", ");
    let subject = match split {
        Split::ObjectSpeed => format!(
            "{} at {} deg/s, {sensors} desynchronized",
            first.object, first.speed_deg_s
        ),
        Split::Fault => format!(
            "{} at {} deg/s, {sensors}: {}",
            first.object,
            first.speed_deg_s,
            fault_text(first.fault)
        ),
    };
    Figure {
        title: format!("Gentle grasp ({target_force_n} N) of the {subject}"),
        x_label: match split {
            Split::ObjectSpeed => "injected delay (ms; for jitter, its bound)".into(),
            Split::Fault => format!("{} (ms)", fault_text(first.fault)),
        },
        y_label: "overshoot of the true peak force (%)".into(),
        x_unit: "ms".into(),
        y_unit: "%".into(),
        series,
        bands: Vec::new(),
        markers: true,
        legend: Some(legend_position(rows)),
    }
}

/// Lower right when every point sits in the upper half of the panel (whose y axis starts
/// at 0 or below), where the legend would hide the lines; upper left otherwise.
fn legend_position(rows: &[&SyncRow]) -> plotters::prelude::SeriesLabelPosition {
    use plotters::prelude::SeriesLabelPosition;
    let ys: Vec<f64> = rows.iter().filter_map(|r| r.overshoot_pct).collect();
    let lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ys.iter().copied().fold(0.0, f64::max);
    if lo.is_finite() && lo > 0.5 * hi {
        SeriesLabelPosition::LowerRight
    } else {
        SeriesLabelPosition::UpperLeft
    }
}

/// Draw `rows` to `out`: one panel as `gelgrip::plot` draws it, several stacked in one SVG.
pub(super) fn save(rows: &[SyncRow], target_force_n: f64, out: &Path) -> anyhow::Result<()> {
    let (split, groups) = panels(rows);
    if groups.len() <= 1 {
        let empty = Vec::new();
        let group = groups.first().unwrap_or(&empty);
        let fig = if group.is_empty() {
            Figure::default()
        } else {
            figure(split, group, target_force_n)
        };
        return crate::plot::save(&fig, out);
    }
    if Format::of(out)? != Format::Svg {
        return Err(crate::args::UsageError(multi_panel_png(out, groups.len())).into());
    }
    let mut svg = String::new();
    for (i, group) in groups.iter().enumerate() {
        crate::plot::save(&figure(split, group, target_force_n), out)?;
        let panel =
            std::fs::read_to_string(out).with_context(|| format!("reading {}", out.display()))?;
        let start = panel.find("<svg").context("a panel without <svg>")?;
        let y = i as u32 * PANEL_H;
        svg += &panel[start..].replacen("<svg", &format!("<svg x=\"0\" y=\"{y}\""), 1);
        svg.push('\n');
    }
    let height = groups.len() as u32 * PANEL_H;
    let svg = format!(
        "<svg width=\"{PANEL_W}\" height=\"{height}\" viewBox=\"0 0 {PANEL_W} {height}\" \
         xmlns=\"http://www.w3.org/2000/svg\">\n{svg}</svg>\n"
    );
    std::fs::write(out, svg).with_context(|| format!("writing {}", out.display()))
}

/// The usage error of a PNG asked for several panels.
pub(super) fn multi_panel_png(out: &Path, panels: usize) -> String {
    format!(
        "{}: these rows plot into {panels} panels (objects and speeds, or faults), which are \
         written as one SVG: use a .svg file",
        out.display()
    )
}
