//! `bench slip --plot`: one trial against time since the load began: the pull as a share
//! of the grip's holding limit, the least true stick ratio of the loaded contacts, the least
//! stick ratio the sensors estimated, and the detection (0 until a sensor reads slip, then
//! 1); shaded, the truth's incipient slip up to gross slip, and the gross slip after.

use std::path::Path;

use super::trial::{SlipRow, TraceSet};
use crate::plot::{Band, Figure, Series, save};

/// Draw `row`'s trial from its `trace` to `path` (.svg or .png).
pub fn draw(row: &SlipRow, trace: &[TraceSet], path: &Path) -> anyhow::Result<()> {
    let limit = row.holding_limit_n.max(f64::MIN_POSITIVE);
    let series = vec![
        Series {
            name: format!("pull / holding limit ({limit:.2} N)"),
            points: trace
                .iter()
                .map(|s| (s.t_s, Some(s.load_n / limit)))
                .collect(),
        },
        Series {
            name: "true stick ratio (least contact)".into(),
            points: trace
                .iter()
                .map(|s| (s.t_s, Some(s.true_stick_ratio)))
                .collect(),
        },
        Series {
            name: "estimated stick ratio (least sensor)".into(),
            points: trace
                .iter()
                .map(|s| (s.t_s, s.estimated_stick_ratio))
                .collect(),
        },
        Series {
            name: "slip detected".into(),
            points: trace
                .iter()
                .map(|s| (s.t_s, Some(if s.detected { 1.0 } else { 0.0 })))
                .collect(),
        },
    ];
    let end = trace.last().map_or(0.0, |s| s.t_s);
    let mut bands = Vec::new();
    if let Some(i) = row.t_incipient_s {
        bands.push(Band {
            from: i,
            to: row.t_gross_s.unwrap_or(end),
            label: "incipient (truth)".into(),
        });
    }
    if let Some(g) = row.t_gross_s {
        bands.push(Band {
            from: g,
            to: end.max(g),
            label: "gross".into(),
        });
    }
    let fig = Figure {
        title: format!(
            "bench slip: {}, μ {}, load time {} s, trial {} (detected {})",
            row.object,
            row.friction,
            row.load_time_s,
            row.trial,
            row.t_detect_s
                .map_or("never".into(), |t| format!("at {t:.3} s"))
        ),
        x_label: "time since the load began".into(),
        y_label: "share".into(),
        x_unit: "s".into(),
        y_unit: String::new(),
        series,
        bands,
        markers: false,
        legend: Some(plotters::prelude::SeriesLabelPosition::UpperLeft),
    };
    save(&fig, path)
}
