//! Requests the page makes of the run loop itself, beyond the grasp API. They belong to the
//! runtime (`gelgrip_controller::runtime::control`); this module re-exports them for the routes.

pub use gelgrip_controller::runtime::control::*;
