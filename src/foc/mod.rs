//! The current loop and the field-oriented transforms it runs on: everything
//! that happens every PWM period.

pub mod current_loop;
pub mod svpwm;
pub mod transforms;

pub use current_loop::{CurrentLoop, CurrentLoopOutput, CurrentTiming};
pub use svpwm::{linear_limit_v, svpwm, SvpwmOutput};
pub use transforms::{clarke, inverse_clarke, inverse_park, park, wrap_pi, AlphaBeta, Dq, SinCos};
