//! `gelgrip plot LOG.csv --out FIG.svg|png`: a task log's deformation signal per sensor over
//! time, with the task's stages shaded and numbered, as in the paper's screwdriver panel
//! (Fig. 6 b4).

use clap::Args;
use std::path::Path;
use std::path::PathBuf;

use anyhow::Context;

use crate::args::UsageError;
use crate::plot::{Band, Figure, Series, save};

const SIGNAL_SUFFIX: &str = "_deformation_mm3";

/// What a task log holds for the plot.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskLog {
    /// Time of each row, s.
    pub t_s: Vec<f64>,
    /// Stage of each row.
    pub stages: Vec<String>,
    /// Per sensor: its id and its deformation signal per row (`None` where missing).
    pub signals: Vec<(String, Vec<Option<f64>>)>,
}

/// Read the CSV log of `gelgrip run --task … --log` at `path`.
pub fn read_log(path: &Path) -> anyhow::Result<TaskLog> {
    let file = path.display().to_string();
    let mut reader = csv::Reader::from_path(path)
        .map_err(|e| UsageError(format!("{file}: cannot read the log: {e}")))?;
    let header = reader
        .headers()
        .map_err(|e| UsageError(format!("{file}: no header row: {e}")))?
        .clone();
    let column = |name: &str| {
        header.iter().position(|h| h == name).ok_or_else(|| {
            UsageError(format!(
                "{file}: no `{name}` column; expected a task log (gelgrip run --task … --log)"
            ))
        })
    };
    let t_col = column("t_s")?;
    let stage_col = column("stage")?;
    let signal_cols: Vec<(usize, String)> = header
        .iter()
        .enumerate()
        .filter_map(|(i, h)| h.strip_suffix(SIGNAL_SUFFIX).map(|id| (i, id.to_string())))
        .collect();
    if signal_cols.is_empty() {
        return Err(UsageError(format!("{file}: no `<sensor>{SIGNAL_SUFFIX}` column")).into());
    }
    let mut log = TaskLog {
        t_s: Vec::new(),
        stages: Vec::new(),
        signals: signal_cols
            .iter()
            .map(|(_, id)| (id.clone(), Vec::new()))
            .collect(),
    };
    for (row, record) in reader.records().enumerate() {
        let line = row + 2;
        let record = record.map_err(|e| UsageError(format!("{file}: line {line}: {e}")))?;
        let cell = |i: usize| record.get(i).unwrap_or("").trim();
        let t: f64 = cell(t_col).parse().map_err(|_| {
            UsageError(format!(
                "{file}: line {line}: t_s = {:?} is not a number",
                cell(t_col)
            ))
        })?;
        if !t.is_finite() || log.t_s.last().is_some_and(|last| t < *last) {
            return Err(UsageError(format!(
                "{file}: line {line}: t_s = {t} (time must be finite and never go back)"
            ))
            .into());
        }
        log.t_s.push(t);
        log.stages.push(cell(stage_col).to_string());
        for ((i, id), (_, values)) in signal_cols.iter().zip(log.signals.iter_mut()) {
            let text = cell(*i);
            let value = if text.is_empty() {
                None
            } else {
                Some(text.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| {
                    UsageError(format!("{file}: line {line}: {id}{SIGNAL_SUFFIX} = {text:?} is not a number"))
                })?)
            };
            values.push(value);
        }
    }
    if log.t_s.is_empty() {
        return Err(UsageError(format!("{file}: the log has no rows")).into());
    }
    Ok(log)
}

/// The stages of `log` as bands: each run of rows in one stage, numbered in order (rows
/// after the task ended, stage `done`, are not a stage).
pub fn stage_bands(log: &TaskLog) -> Vec<Band> {
    let mut bands: Vec<Band> = Vec::new();
    for (i, (t, stage)) in log.t_s.iter().zip(&log.stages).enumerate() {
        if stage == "done" {
            if let Some(b) = bands.last_mut() {
                b.to = b.to.max(*t);
            }
            continue;
        }
        match bands.last_mut() {
            Some(b) if i > 0 && log.stages[i - 1] == *stage => b.to = *t,
            _ => {
                if let Some(b) = bands.last_mut() {
                    b.to = *t;
                }
                bands.push(Band {
                    from: *t,
                    to: *t,
                    label: format!("{} {stage}", bands.len() + 1),
                });
            }
        }
    }
    bands
}

/// The figure of `log`.
pub fn figure(log: &TaskLog, title: &str) -> Figure {
    Figure {
        title: title.to_string(),
        x_label: "time (s)".into(),
        y_label: "deformation signal (mm³)".into(),
        x_unit: "s".into(),
        y_unit: "mm³".into(),
        series: log
            .signals
            .iter()
            .map(|(id, values)| Series {
                name: id.clone(),
                points: log
                    .t_s
                    .iter()
                    .copied()
                    .zip(values.iter().copied())
                    .collect(),
            })
            .collect(),
        bands: stage_bands(log),
        markers: false,
        legend: Some(plotters::prelude::SeriesLabelPosition::MiddleLeft),
    }
}

/// Run the command.
pub fn run(args: PlotArgs) -> anyhow::Result<u8> {
    crate::plot::Format::of(&args.out)?;
    let log = read_log(&args.log)?;
    let title = args.title.unwrap_or_else(|| {
        format!(
            "Deformation signal per sensor: {}",
            args.log
                .file_name()
                .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
        )
    });
    save(&figure(&log, &title), &args.out)?;
    let bands = stage_bands(&log);
    eprintln!(
        "{}: {} sensors, {} rows over {:.1} s, {} stages",
        args.out.display(),
        log.signals.len(),
        log.t_s.len(),
        log.t_s.last().copied().unwrap_or(0.0) - log.t_s[0],
        bands.len()
    );
    std::fs::metadata(&args.out)
        .with_context(|| format!("{} was not written", args.out.display()))?;
    Ok(0)
}

/// `gelgrip plot`.
#[derive(Debug, Args)]
pub struct PlotArgs {
    /// The CSV log.
    pub log: PathBuf,
    /// The figure: `.svg` or `.png`.
    #[arg(long)]
    pub out: PathBuf,
    /// Title (default: names the log).
    #[arg(long)]
    pub title: Option<String>,
}
