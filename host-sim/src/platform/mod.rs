//! The 6-DOF Stewart platform the cylinder is one leg of (paper §2.1,
//! Table 3): geometry, kinematics, Jacobian, pose error, rigid-body
//! dynamics and leg forces, pose trajectories, the Table 4 reproduction.
//! Conventions are stated in `geometry` and `kinematics` and in
//! docs/platform.md.

pub mod dynamics;
pub mod geometry;
pub mod kinematics;
mod leg_threads;
pub mod plots;
pub mod pose_error;
pub mod run;
pub mod six_legs;
pub mod stream;
pub mod stream_report;
pub mod table4;
pub mod table4_md;
pub mod trajectory;

pub use dynamics::{LegForces, PoseState, GRAVITY_M_S2};
pub use geometry::Geometry;
pub use kinematics::{ForwardSolution, KinematicsError, Legs, Platform, Pose};
pub use pose_error::{PoseError, PoseErrorEstimate};
pub use trajectory::Trajectory;
