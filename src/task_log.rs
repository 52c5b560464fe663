//! The task CSV (`--log OUT.csv`): one row per set a task drove (time, stage, deformation
//! per sensor, true force per sensor on the simulator, and per finger its state, force,
//! goal current and position; on a layout with marker gels, then the slip per finger and
//! of the grasp, docs/slip.md). Lossless: a write failure is a fault of the run.

use std::io::Write;
use std::path::Path;

use gelgrip_controller::layout::HandLayout;
use gelgrip_controller::runtime::plant::phase_name;
use gelgrip_controller::runtime::ports::{Observer, ObserverError};
use gelgrip_controller::runtime::report::SetReport;

/// The CSV log of a task.
#[derive(Debug)]
pub struct TaskLog {
    out: std::io::BufWriter<std::fs::File>,
    /// Whether the rows end with the slip columns (a layout with marker gels).
    slip: bool,
}

impl TaskLog {
    /// Create `path` with its header for `layout`; `truth` adds the simulator's pad forces.
    pub fn create(path: &Path, layout: &HandLayout, truth: bool) -> crate::Result<Self> {
        let file = std::fs::File::create(path)
            .map_err(|e| crate::Error::io(format!("creating the log {}", path.display()), e))?;
        let mut out = std::io::BufWriter::new(file);
        let mut header = vec!["t_s".to_string(), "stage".to_string()];
        header.extend(
            layout
                .sensors
                .iter()
                .map(|s| format!("{}_deformation_mm3", s.id)),
        );
        if truth {
            header.extend(
                layout
                    .sensors
                    .iter()
                    .map(|s| format!("{}_true_force_n", s.id)),
            );
        }
        for f in &layout.fingers {
            header.push(format!("{}_state", f.id));
            header.push(format!("{}_force_n", f.id));
            header.push(format!("{}_goal_current_ma", f.id));
            header.push(format!("{}_position_deg", f.id));
        }
        let slip = layout.sensors.iter().any(|s| s.markers.is_some());
        if slip {
            for f in &layout.fingers {
                header.push(format!("{}_slip", f.id));
                header.push(format!("{}_stick_ratio", f.id));
            }
            header.push("grasp_slip".to_string());
        }
        writeln!(out, "{}", header.join(","))
            .map_err(|e| crate::Error::io(format!("writing the log {}", path.display()), e))?;
        Ok(Self { out, slip })
    }
}

impl Observer for TaskLog {
    fn observe(&mut self, report: &SetReport<'_>) -> Result<(), ObserverError> {
        let Some(g) = report.gripper.as_ref() else {
            return Ok(());
        };
        let (Some(step), Some(fused)) = (g.step, g.fused) else {
            return Ok(());
        };
        let servos = report.servos.map_or(&[][..], |s| s.states);
        let mut cells = vec![format!("{:.4}", step.t_s), step.stage.clone()];
        cells.extend(
            fused
                .deformation_mm3
                .iter()
                .map(|d| d.map_or(String::new(), |v| format!("{v:.4}"))),
        );
        cells.extend(step.truth_n.iter().map(|f| format!("{f:.4}")));
        for (i, (p, f)) in step.phases.iter().zip(&fused.fingers).enumerate() {
            cells.push(phase_name(*p).to_string());
            cells.push(format!("{:.4}", f.force_n));
            cells.push(
                step.goals
                    .get(i)
                    .map_or(String::new(), |g| format!("{:.1}", g.goal_current_ma)),
            );
            cells.push(
                servos
                    .get(i)
                    .map_or(String::new(), |s| format!("{:.2}", s.position_deg)),
            );
        }
        if self.slip {
            // Empty where the slip is unknown (no marker dots under a contact).
            for f in &fused.fingers {
                cells.push(
                    f.slip
                        .map_or(String::new(), |s| s.state.as_str().to_string()),
                );
                cells.push(
                    f.slip
                        .map_or(String::new(), |s| format!("{:.2}", s.stick_ratio)),
                );
            }
            cells.push(
                fused
                    .slip()
                    .map_or(String::new(), |s| s.state.as_str().to_string()),
            );
        }
        writeln!(self.out, "{}", cells.join(","))?;
        Ok(())
    }

    fn finish(&mut self) -> Result<(), ObserverError> {
        self.out
            .flush()
            .map_err(|e| format!("could not flush the task log: {e}").into())
    }
}
