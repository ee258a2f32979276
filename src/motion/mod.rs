//! Everything above the current loop: encoder tracking, the speed and position
//! loops, and the trajectory that feeds them.

pub mod encoder;
pub mod position_loop;
pub mod speed_loop;
pub mod stop;
pub mod stream;
pub mod stream_stop;
pub mod trajectory;

pub use encoder::{EncoderTracker, EncoderUpdate};
pub use position_loop::{position_step, PositionLoopOutput};
pub use speed_loop::{SpeedLoop, SpeedLoopOutput};
pub use stop::StopRamp;
pub use stream::{Setpoint, SetpointStream};
pub use trajectory::{ScurveMove, TrajectorySample};
