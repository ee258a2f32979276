//! Control core of the direct-driven servo electric cylinder.
//!
//! HAL-free and `no_std`: the STM32 firmware and the host simulator compile
//! this same code. One call, [`Controller::step`], advances one PWM period
//! from a [`SensorSample`] to a [`PwmCommand`]; the outer loops run decimated
//! inside it. `f32` throughout, no allocation, no panics, deterministic.
//!
//! Layout: `foc/` is the current loop (every PWM period), `motion/` the
//! encoder tracking, speed and position loops and the trajectory, `protection/`
//! faults and limits, `params` every gain, rate and limit, `reason` why a
//! request is refused. `protocol` carries these words over a link and sits on
//! top: nothing else in the core imports it.
#![no_std]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]
#![warn(missing_debug_implementations)]
// `!(x < y)` is how this crate says "not less, or NaN": the negation is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod capture;
pub mod compensation;
pub mod controller;
pub mod filters;
pub mod foc;
pub mod io;
pub mod lifecycle;
pub mod load_estimate;
pub mod mailbox;
pub mod math;
pub mod motion;
pub mod observer;
pub mod params;
pub mod pi;
pub mod protection;
pub mod protocol;
pub mod reason;
pub mod telemetry;
pub mod test_signals;

pub use controller::{Command, CommandError, CommandOutcome, Controller};
pub use io::{PwmCommand, SensorSample};
pub use params::{ControlParams, ParamError};
pub use protection::{FaultSet, LimitFlags};
pub use reason::Reason;
pub use lifecycle::Readiness;
pub use telemetry::{Mode, Telemetry};
