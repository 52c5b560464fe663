//! gelgrip's simulated world, a product backend selected with `hub.transport = "sim"`.
//!
//! - [`scene`]: what presses on each sensor (built-in static presses until scene physics
//!   arrives with the actuation issue);
//! - [`gel`]: the gel's skirt around a ball's contact (the realistic simulator's mechanics);
//! - [`optics`]: a physically grounded image model: Lambertian shading of the indented gel
//!   under three coloured side lights, with per-unit LED gain and offset, vignetting and
//!   seeded noise;
//! - [`pool`]: the JPEG frames each sensor produces;
//! - [`timeline`]: the hub's bus at the transaction level (I2C trigger bits, board
//!   buffering, SPI transfer of each frame's actual length), which produces every timestamp;
//! - [`hub`]: [`hub::SimHub`], the `HubTransport` that plays that timeline on the injected
//!   clock, with fault injection from config; [`board_clock`]: a board's drifting clock;
//! - [`fault_storm`]: a seeded storm of faults in virtual time (the virtual-clock soak);
//! - [`config`] and [`factory`]: the `[hub.sim]` section and the registry entry;
//! - the world: [`shapes`] and [`scene_spec`] (scene files), [`object`] (slip, crush, the
//!   screwdriver's trigger and bolt), [`finger`] (cable-driven finger mechanics),
//!   [`contact`] (gel indentation and force), [`motor`] (the XM430 model), [`world`] (all of
//!   it stepped in simulated time, with a [`world_log`]) and [`servo_bus`] (the simulated
//!   `ServoBus`).
//! - beside the controller's ports: [`press_camera`] (a sensor's camera as the
//!   calibration's `PressCamera`), [`truth`] (the world as its `GroundTruth`), [`scene_report`]
//!   (the `scene` object of `run --json`) and [`press_requests`] (`emulate hub --presses`:
//!   presses and weights asked for on a pipe, answered as JSON lines).

pub mod board_cameras;
pub mod board_clock;
pub mod config;
pub mod contact;
pub mod factory;
pub mod fault_storm;
pub mod finger;
pub mod gel;
pub mod hub;
pub mod load;
pub mod markers;
pub mod motor;
pub mod object;
pub mod optics;
pub mod pool;
pub mod press_camera;
pub mod press_requests;
pub mod scene;
pub mod scene_frames;
pub mod scene_report;
pub mod scene_spec;
pub mod servo_bus;
pub mod servo_fault_plan;
pub mod shapes;
pub mod timeline;
pub mod traction;
pub mod truth;
pub mod unit;
pub mod weights;
pub mod world;
pub mod world_log;

pub use factory::SimHubFactory;
