//! Ball presses and weights on request, for the emulated hubs: request lines (`SENSOR X_PX
//! Y_PX DEPTH_MM [BALL_MM]`, `SENSOR lift`, `SENSOR GRAMS`) change what the simulated boards
//! show ([`crate::weights`]), each answered by one JSON line ([`serve`]).
//!
//! The CDC hub emulator (`gelgrip emulate hub --presses-on-stdin`) reads them on its stdin.
//! The CH347 chip emulator runs inside the command that opens it, so its requests come
//! through a named pipe: `[hub.ch347.emulator] presses_from = "PATH"` ([`RequestedPresses`])
//! makes every board start untouched and reads PATH's lines, reopening it whenever a writer
//! closes it (answers go to the log).

use std::io::{BufRead, Write};
use std::path::PathBuf;

use crate::board_cameras::SimCameraSource;
use crate::config::SimConfig;
use crate::weights::{WeightControl, weighted_cameras};
use gelgrip_controller::camera::{BoardCameras, CameraSource};
use gelgrip_controller::config::{BackendSection, ConfigError};
use gelgrip_controller::layout::HandLayout;

/// The emulator key naming the pipe of requests.
pub const PRESSES_FROM: &str = "presses_from";

/// A [`CameraSource`] for the CH347 emulator: the simulator's boards, showing presses on
/// request when the emulator section has [`PRESSES_FROM`], else as `inner` shows them.
#[derive(Debug, Clone, Default)]
pub struct RequestedPresses {
    inner: SimCameraSource,
}

impl RequestedPresses {
    /// Boards as `inner` shows them, unless presses are requested.
    pub fn new(inner: SimCameraSource) -> Self {
        Self { inner }
    }
}

/// The section without [`PRESSES_FROM`] (the simulator's keys), and the pipe it names.
fn split(section: &BackendSection) -> Result<(BackendSection, Option<PathBuf>), ConfigError> {
    let mut sim = section.clone();
    let path = match sim.table.remove(PRESSES_FROM) {
        None => None,
        Some(toml::Value::String(p)) if !p.is_empty() => Some(section.base_dir.join(p)),
        Some(other) => {
            return Err(section.check.invalid(
                &format!("{}.{PRESSES_FROM}", section.prefix),
                other,
                "a path: a named pipe (mkfifo) of press requests",
            ));
        }
    };
    Ok((sim, path))
}

impl CameraSource for RequestedPresses {
    fn validate(&self, section: &BackendSection, layout: &HandLayout) -> Result<(), ConfigError> {
        let (sim, _) = split(section)?;
        self.inner.validate(&sim, layout)
    }

    fn open(
        &self,
        section: &BackendSection,
        layout: &HandLayout,
    ) -> Result<(Box<dyn BoardCameras>, Option<f64>), String> {
        let (sim_section, path) = split(section).map_err(|e| e.to_string())?;
        let Some(path) = path else {
            return self.inner.open(&sim_section, layout);
        };
        let sim = SimConfig::from_section(&sim_section, layout).map_err(|e| e.to_string())?;
        let (cameras, control) = weighted_cameras(layout, &sim).map_err(|e| e.to_string())?;
        let (layout, ball_mm) = (layout.clone(), sim.ball_diameter_mm);
        std::thread::Builder::new()
            .name("press requests".into())
            .spawn(move || {
                loop {
                    // Blocks until a writer opens the pipe; ends at the writer's close.
                    match std::fs::File::open(&path) {
                        Ok(f) => serve(
                            std::io::BufReader::new(f),
                            LogAnswers,
                            &layout,
                            &control,
                            ball_mm,
                        ),
                        Err(e) => {
                            tracing::error!("press requests: {}: {e}", path.display());
                            return;
                        }
                    }
                }
            })
            .map_err(|e| format!("starting the press-request reader: {e}"))?;
        Ok((Box::new(cameras), None))
    }
}

/// Answers written to the log, a line each.
struct LogAnswers;

impl Write for LogAnswers {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let text = String::from_utf8_lossy(buf);
        let text = text.trim();
        if !text.is_empty() {
            tracing::info!("press request: {text}");
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Read request lines from `input` until it ends: `SENSOR GRAMS` places a weight, `SENSOR
/// X_PX Y_PX DEPTH_MM [BALL_MM]` presses a ball (`ball_mm` unless given), `SENSOR lift`
/// lifts it; each is answered with one JSON line on `output`.
pub fn serve(
    input: impl BufRead,
    mut output: impl Write,
    layout: &HandLayout,
    control: &WeightControl,
    ball_mm: f64,
) {
    for line in input.lines() {
        let Ok(line) = line else { break };
        if line.trim().is_empty() {
            continue;
        }
        let words: Vec<&str> = line.split_whitespace().collect();
        let answer = if words.len() == 2 && words[1] != "lift" {
            place_weight(layout, control, &line)
        } else {
            press_ball(layout, control, &line, ball_mm)
        };
        let _ = writeln!(output, "{answer}");
        let _ = output.flush();
    }
}

/// Place the weight one request line asks for; the JSON answer.
fn place_weight(layout: &HandLayout, control: &WeightControl, line: &str) -> serde_json::Value {
    let mut words = line.split_whitespace();
    let (sensor, grams) = (words.next().unwrap_or(""), words.next());
    let fail = |why: String| {
        tracing::warn!("weights: `{line}`: {why}");
        serde_json::json!({ "sensor": sensor, "weight_g": grams, "error": why })
    };
    let Some(board) = layout.index_of(sensor) else {
        return fail(format!(
            "no sensor `{sensor}`; sensors: {}",
            layout.id_list()
        ));
    };
    let Some(Ok(g)) = grams.map(str::parse::<f64>) else {
        return fail("expected `SENSOR GRAMS`, e.g. `f1.tip 100`".into());
    };
    if words.next().is_some() {
        return fail("expected `SENSOR GRAMS`, e.g. `f1.tip 100`".into());
    }
    match control.place(board, g) {
        Ok(p) => serde_json::json!({
            "sensor": sensor,
            "weight_g": p.grams,
            "force_n": p.force_n,
            "depth_mm": p.depth_mm,
        }),
        Err(e) => fail(e.to_string()),
    }
}

/// Press or lift the ball one request line asks for (`SENSOR X_PX Y_PX DEPTH_MM [BALL_MM]`
/// or `SENSOR lift`); the JSON answer.
fn press_ball(
    layout: &HandLayout,
    control: &WeightControl,
    line: &str,
    ball_mm: f64,
) -> serde_json::Value {
    let words: Vec<&str> = line.split_whitespace().collect();
    let sensor = words.first().copied().unwrap_or("");
    let fail = |why: String| {
        tracing::warn!("presses: `{line}`: {why}");
        serde_json::json!({ "sensor": sensor, "error": why })
    };
    let Some(board) = layout.index_of(sensor) else {
        return fail(format!(
            "no sensor `{sensor}`; sensors: {}",
            layout.id_list()
        ));
    };
    if words.len() == 2 && words[1] == "lift" {
        return match control.place(board, 0.0) {
            Ok(_) => serde_json::json!({ "sensor": sensor, "lifted": true }),
            Err(e) => fail(e.to_string()),
        };
    }
    let nums: Option<Vec<f64>> = words[1..].iter().map(|w| w.parse().ok()).collect();
    let Some(nums) = nums.filter(|n| n.len() == 3 || n.len() == 4) else {
        return fail("expected `SENSOR X_PX Y_PX DEPTH_MM [BALL_MM]` or `SENSOR lift`".into());
    };
    let ball = nums.get(3).copied().unwrap_or(ball_mm);
    match control.press_ball(board, (nums[0], nums[1]), ball, nums[2]) {
        Ok(p) => serde_json::json!({
            "sensor": sensor,
            "center_x_px": p.center_x_px,
            "center_y_px": p.center_y_px,
            "depth_mm": p.depth_mm,
            "ball_mm": p.ball_mm,
            "contact_radius_px": p.contact_radius_px,
        }),
        Err(e) => fail(e.to_string()),
    }
}
