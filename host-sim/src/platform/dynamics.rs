//! Rigid-body dynamics of the moving plate and payload (Eq. 1) and each
//! leg's axial force through Jᵀ.
//!
//! Newton–Euler about the centre of mass, in the base frame:
//!   F = m (a_c − g),   M_c = I ω̇ + ω × I ω,   I = R I_body Rᵀ,
//! moved to the platform origin (M = M_c + R c × F). The legs supply that
//! wrench: Σ f_i u_i = F, Σ (R a_i × u_i) f_i = M, i.e. Jᵀ f = (F, M) with J
//! the twist Jacobian, so f = J⁻ᵀ (F, M). This is Eq. 1 with M_s q̈ + C_s q̇
//! + G_s written out, in twist rather than Euler-rate coordinates (the two
//! differ by the invertible map E of `euler_rate_matrix`).
//! f_i > 0: leg i pushes the plate (compression). Leg masses are not in it.

use super::kinematics::{euler_rate_matrix, euler_rate_matrix_dot, twist_jacobian, KinematicsError, Legs, Platform, Pose};
use nalgebra::{Vector3, Vector6};

pub const GRAVITY_M_S2: f64 = 9.80665;

/// Pose with its first two time derivatives (Euler-angle rates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseState {
    pub pose: Pose,
    pub velocity: Vector6<f64>,
    pub acceleration: Vector6<f64>,
}

/// Plate motion in the base frame at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlateMotion {
    pub com_acceleration: Vector3<f64>,
    pub angular_velocity: Vector3<f64>,
    pub angular_acceleration: Vector3<f64>,
}

/// Legs and their axial forces at one instant.
#[derive(Clone, Debug, PartialEq)]
pub struct LegForces {
    pub legs: Legs,
    /// Compression positive.
    pub forces_n: [f64; 6],
    /// The wrench the legs supply at the platform origin: (F, M).
    pub wrench: Vector6<f64>,
}

impl Platform {
    /// Plate motion from the pose state (no workspace check).
    pub fn plate_motion(&self, s: &PoseState) -> PlateMotion {
        let euler = s.pose.euler_rad;
        let rates: Vector3<f64> = s.velocity.fixed_rows::<3>(3).into();
        let accels: Vector3<f64> = s.acceleration.fixed_rows::<3>(3).into();
        let e = euler_rate_matrix(&euler);
        let omega = e * rates;
        let alpha = e * accels + euler_rate_matrix_dot(&euler, &rates) * rates;
        let rc = s.pose.rotation() * self.geometry.com_body();
        let a_origin: Vector3<f64> = s.acceleration.fixed_rows::<3>(0).into();
        let com_acceleration = a_origin + alpha.cross(&rc) + omega.cross(&omega.cross(&rc));
        PlateMotion { com_acceleration, angular_velocity: omega, angular_acceleration: alpha }
    }

    /// The wrench (F, M about the platform origin) the legs must supply.
    pub fn required_wrench(&self, s: &PoseState) -> Vector6<f64> {
        let g = &self.geometry;
        let m = self.plate_motion(s);
        let r = s.pose.rotation();
        let inertia = r.matrix() * g.inertia_body() * r.matrix().transpose();
        let force = g.payload_mass_kg * (m.com_acceleration - Vector3::new(0.0, 0.0, -GRAVITY_M_S2));
        let moment_c = inertia * m.angular_acceleration + m.angular_velocity.cross(&(inertia * m.angular_velocity));
        let moment = moment_c + (r * g.com_body()).cross(&force);
        Vector6::new(force.x, force.y, force.z, moment.x, moment.y, moment.z)
    }

    /// Each leg's axial force at the pose state; the pose must lie in the
    /// workspace.
    pub fn leg_forces(&self, s: &PoseState) -> Result<LegForces, KinematicsError> {
        let legs = self.inverse_checked(&s.pose)?;
        let wrench = self.required_wrench(s);
        let jt = twist_jacobian(&legs).transpose();
        // Not singular: `inverse_checked` refused that.
        let f = jt.lu().solve(&wrench).ok_or(KinematicsError::SingularJacobian)?;
        Ok(LegForces { legs, forces_n: f.into(), wrench })
    }
}
