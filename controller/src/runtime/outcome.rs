//! Typed outcomes of a run: why it ended, and why a task script stopped. Each serialises to
//! the string CONTRACTS.md gives it (`end_reason`).

use serde::Serialize;

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
}
