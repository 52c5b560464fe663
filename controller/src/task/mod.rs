//! Task scripts: sequences of stages, each with finger targets (force, position, current
//! or open), tactile exit conditions (contact on a named sensor, depth, force, area
//! change, the deformation signal's rise or slope), a timeout and failure branches.
//! [`script`] parses and validates the TOML; [`runner`] steps it once per gated set.

pub mod runner;
pub mod script;
pub mod signals;

pub use runner::{StageExit, StageRecord, TaskEnd, TaskRunner};
pub use script::{ScriptError, TaskScript};

#[cfg(test)]
mod tests;
