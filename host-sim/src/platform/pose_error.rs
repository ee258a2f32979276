//! Pose error from leg errors (Eq. 6): linearised, δq = J_q⁻¹ δl, and
//! exact, δq = FK(l + δl) − FK(l), with the difference between the two.

use super::kinematics::{KinematicsError, Platform, Pose};
use nalgebra::{Vector3, Vector6};

/// A pose error split into position (m) and attitude (rad, Euler-angle
/// differences roll, pitch, yaw).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PoseError {
    pub position_m: [f64; 3],
    pub attitude_rad: [f64; 3],
}

impl PoseError {
    pub fn from_vector(d: &Vector6<f64>) -> Self {
        Self { position_m: [d[0], d[1], d[2]], attitude_rad: [d[3], d[4], d[5]] }
    }

    pub fn to_vector(&self) -> Vector6<f64> {
        let [x, y, z] = self.position_m;
        let [a, b, c] = self.attitude_rad;
        Vector6::new(x, y, z, a, b, c)
    }

    pub fn position_norm_m(&self) -> f64 {
        Vector3::from(self.position_m).norm()
    }

    pub fn attitude_norm_rad(&self) -> f64 {
        Vector3::from(self.attitude_rad).norm()
    }
}

/// Both estimates of the pose error caused by `errors_m` on `nominal_m`.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseErrorEstimate {
    pub nominal: Pose,
    pub exact: PoseError,
    pub linear: PoseError,
}

impl PoseErrorEstimate {
    /// Linear minus exact.
    pub fn difference(&self) -> PoseError {
        PoseError::from_vector(&(self.linear.to_vector() - self.exact.to_vector()))
    }
}

impl Platform {
    /// The pose error of leg lengths `nominal_m + errors_m` against
    /// `nominal_m`, both solved by forward kinematics from `guess`.
    pub fn pose_error(&self, nominal_m: &[f64; 6], errors_m: &[f64; 6], guess: &Pose) -> Result<PoseErrorEstimate, KinematicsError> {
        let nominal = self.forward(nominal_m, guess)?.pose;
        let actual: [f64; 6] = std::array::from_fn(|i| nominal_m[i] + errors_m[i]);
        let moved = self.forward(&actual, &nominal)?.pose;
        let exact = moved.to_vector() - nominal.to_vector();
        let linear = self
            .pose_jacobian(&nominal)
            .lu()
            .solve(&Vector6::from(*errors_m))
            .ok_or(KinematicsError::SingularJacobian)?;
        Ok(PoseErrorEstimate { nominal, exact: PoseError::from_vector(&exact), linear: PoseError::from_vector(&linear) })
    }
}
