//! Typed outcomes of a run: what it ended with ([`RunSummary`]), why it ended, why a task script stopped, and the faults met on
//! the way. Each serialises to the string CONTRACTS.md gives it (`end_reason`, the entries
//! of `faults`).

use serde::Serialize;

use crate::actuator::{RecoveredFault, ServoError, ServoState};
use crate::runtime::task_report::TaskReport;

/// Why a run ended (`end_reason` in `run --json`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EndReason {
    /// The task finished, or the hub's source (a recording) ran out.
    Done,
    /// The requested duration passed.
    Duration,
    /// SIGINT or SIGTERM (or the embedding program's shutdown).
    Signal,
    /// A fault that was not recovered.
    Fault,
    /// An e-stop.
    Estop,
}

impl EndReason {
    /// The contract's string.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Done => "done",
            Self::Duration => "duration",
            Self::Signal => "signal",
            Self::Fault => "fault",
            Self::Estop => "estop",
        }
    }

    /// The exit code CONTRACTS.md gives it: 1 for a fault or an e-stop, else 0.
    pub fn exit_code(self) -> u8 {
        match self {
            Self::Fault | Self::Estop => 1,
            Self::Done | Self::Duration | Self::Signal => 0,
        }
    }
}

impl std::fmt::Display for EndReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What kind of fault a run met: the loop tells a servo timeout from a hardware fault from
/// a hub failure without reading strings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// A servo's hardware fault that a reboot cleared (the run goes on).
    ServoRecovered,
    /// A servo did not answer in time.
    ServoTimeout,
    /// A servo's reply failed its checks.
    ServoCorrupt,
    /// A servo refused an instruction.
    ServoInstruction,
    /// A servo's hardware fault that reboots did not clear.
    ServoHardware,
    /// The servo bus itself failed, or was asked for the impossible.
    ServoBus,
    /// The hub failed.
    Hub,
    /// No synchronized set in time: every finger held.
    Watchdog,
    /// An e-stop was requested.
    Estop,
    /// A lossless observer (the task log, the recorder) failed.
    Observer,
    /// The run could not start as asked (no references, no fingers, the grasp API).
    Setup,
}

/// A fault a run met, with its evidence as the run reports it (`faults` in `run --json`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Fault {
    /// What kind.
    pub kind: FaultKind,
    /// The evidence, as reported.
    pub detail: String,
}

impl Fault {
    /// A fault of `kind` with `detail`.
    pub fn new(kind: FaultKind, detail: impl Into<String>) -> Self {
        Self {
            kind,
            detail: detail.into(),
        }
    }

    /// A servo error, as the loop reports it (`servo fault: …`).
    pub fn servo(e: &ServoError) -> Self {
        let kind = match e {
            ServoError::Timeout { .. } => FaultKind::ServoTimeout,
            ServoError::Corrupt { .. } => FaultKind::ServoCorrupt,
            ServoError::Instruction { .. } => FaultKind::ServoInstruction,
            ServoError::HardwareFault { .. } => FaultKind::ServoHardware,
            ServoError::Bus(_) | ServoError::Invalid(_) => FaultKind::ServoBus,
        };
        Self::new(kind, format!("servo fault: {e}"))
    }

    /// A hardware fault that a reboot cleared.
    pub fn recovered(r: &RecoveredFault) -> Self {
        Self::new(FaultKind::ServoRecovered, r.to_string())
    }
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.detail)
    }
}

/// How a set or a command left a task script that was running.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScriptEnd {
    /// It reached `done` or aborted on its own.
    Finished,
    /// A release or stop from the grasp API interrupted it.
    Interrupted,
    /// An e-stop from the grasp API interrupted it.
    Estop,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fault_log_keeps_the_first_faults_and_counts_the_rest() {
        let fault = |n: usize| Fault::new(FaultKind::Watchdog, format!("fault {n}"));
        let mut earlier = FaultLog::default();
        earlier.extend((0..200).map(fault));
        let mut later = FaultLog::default();
        later.extend((200..1000).map(fault));
        assert_eq!(
            (later.faults().len(), later.omitted()),
            (FAULTS_KEPT, 800 - FAULTS_KEPT as u64)
        );
        let log = later.after(earlier);
        assert_eq!(log.faults().len(), FAULTS_KEPT);
        assert_eq!(log.omitted(), 1000 - FAULTS_KEPT as u64);
        assert_eq!(log.faults()[0].detail, "fault 0");
        assert_eq!(
            log.faults()[FAULTS_KEPT - 1].detail,
            format!("fault {}", FAULTS_KEPT - 1)
        );
    }

    #[test]
    fn end_reasons_serialise_to_the_contracts_strings() {
        for (reason, text) in [
            (EndReason::Done, "done"),
            (EndReason::Duration, "duration"),
            (EndReason::Signal, "signal"),
            (EndReason::Fault, "fault"),
            (EndReason::Estop, "estop"),
        ] {
            assert_eq!(reason.as_str(), text);
            assert_eq!(reason.to_string(), text);
        }
        assert_eq!(EndReason::Fault.exit_code(), 1);
        assert_eq!(EndReason::Signal.exit_code(), 0);
    }

    #[test]
    fn a_servo_timeout_and_a_hardware_fault_are_told_apart_and_read_as_before() {
        let timeout = Fault::servo(&ServoError::Timeout {
            id: 2,
            detail: "read state".into(),
        });
        let hardware = Fault::servo(&ServoError::HardwareFault {
            id: 2,
            bits: 0x04,
            tries: 2,
        });
        assert_eq!(timeout.kind, FaultKind::ServoTimeout);
        assert_eq!(hardware.kind, FaultKind::ServoHardware);
        assert_eq!(
            hardware.to_string(),
            "servo fault: servo 2: hardware error 0x04 persists after 2 reboot(s)"
        );
        let recovered = Fault::recovered(&RecoveredFault {
            finger: 1,
            id: 2,
            bits: 0x20,
            tries: 1,
        });
        assert_eq!(recovered.kind, FaultKind::ServoRecovered);
        assert_eq!(
            recovered.to_string(),
            "servo 2 (finger 2): overload recovered after 1 reboot(s)"
        );
    }
}

/// Faults a run keeps in full; beyond them it counts (a soak meets thousands).
pub const FAULTS_KEPT: usize = 256;

/// The faults of a run, bounded: the first [`FAULTS_KEPT`] in full, the rest counted.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FaultLog {
    kept: Vec<Fault>,
    omitted: u64,
}

impl FaultLog {
    /// Keep `fault`, or count it once the log is full.
    pub fn push(&mut self, fault: Fault) {
        if self.kept.len() < FAULTS_KEPT {
            self.kept.push(fault);
        } else {
            self.omitted += 1;
        }
    }

    /// Keep each of `faults` in turn.
    pub fn extend(&mut self, faults: impl IntoIterator<Item = Fault>) {
        for f in faults {
            self.push(f);
        }
    }

    /// `earlier` before these faults, within the bound.
    pub fn after(self, earlier: FaultLog) -> FaultLog {
        let mut log = earlier;
        let omitted = self.omitted;
        log.extend(self.kept);
        log.omitted += omitted;
        log
    }

    /// The faults kept.
    pub fn faults(&self) -> &[Fault] {
        &self.kept
    }

    /// Faults counted beyond the kept ones.
    pub fn omitted(&self) -> u64 {
        self.omitted
    }
}

/// What a run ended with, once the hardware is safe.
#[derive(Debug, Clone)]
pub struct RunSummary {
    /// Why it ended.
    pub end_reason: EndReason,
    /// Faults, recovered ones first: the first [`FAULTS_KEPT`] in full, the rest counted.
    pub faults: FaultLog,
    /// Sets delivered whose trigger sequence was not past the last set's (a set delivered
    /// twice, or out of order): 0 in a sound run.
    pub duplicate_sets: u64,
    /// The task fields (none without a task).
    pub task: Option<TaskReport>,
    /// The servos' last states, in finger order (none without servos).
    pub servos: Option<Vec<ServoState>>,
    /// Run time on the runtime's clock, from [`Runtime::run`]'s start (or the first step).
    pub elapsed_s: f64,
    /// What the sensors said of slip (none without a pilot: nothing was sensed).
    pub slip: Option<crate::runtime::slip_tally::SlipTally>,
}
