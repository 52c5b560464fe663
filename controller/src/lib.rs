//! gelgrip's application kernel: core types, the ports every adapter implements, the
//! synchronized-frame gate, configuration and the acquisition loop.
//!
//! This crate depends on no adapter. Hub transports (`backends/*`) implement
//! [`hub::HubTransport`] and register a [`registry::HubFactory`]; only the `gelgrip` binary
//! wires concrete adapters together. Time is injected through [`clock::Clock`], so the same
//! code runs in real time or in deterministic virtual time.

pub mod acquire;
pub mod actuator;
pub mod camera;
pub mod clock;
pub mod config;
pub mod fingers;
pub mod frame;
pub mod fusion;
pub mod gate;
pub mod grasp;
pub mod grasp_goals;
pub mod gripper;
pub mod hub;
pub mod hubtime;
pub mod layout;
pub mod markers;
#[cfg(test)]
mod parser_fuzz;
pub mod registry;
pub mod runtime;
pub mod task;
