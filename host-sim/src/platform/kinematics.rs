//! Inverse kinematics (Eq. 2), the Jacobians (Eqs. 3–6) and forward
//! kinematics by Newton–Raphson on the inverse kinematics.
//!
//! Pose q = (x, y, z, roll φ, pitch θ, yaw ψ): the platform frame's origin in
//! the base frame and R = R_z(ψ) R_y(θ) R_x(φ) (nalgebra's
//! `Rotation3::from_euler_angles(φ, θ, ψ)`). Leg i: l_i u_i = p + R a_i − b_i.

use super::geometry::{Geometry, Joints};
use nalgebra::{Matrix3, Matrix6, Rotation3, Vector3, Vector6};
use std::fmt;

/// Newton stops when every leg length matches to this.
pub const FK_TOLERANCE_M: f64 = 1e-12;
pub const FK_MAX_ITERATIONS: usize = 50;
/// Refused as singular below this inverse condition number of the twist
/// Jacobian with its angular columns scaled by the top radius (a 1 µm leg
/// error would then move the plate by more than about 1 mm).
pub const MIN_INVERSE_CONDITION: f64 = 1e-3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub position_m: Vector3<f64>,
    /// (roll φ, pitch θ, yaw ψ).
    pub euler_rad: Vector3<f64>,
}

impl Pose {
    pub fn new(position_m: Vector3<f64>, euler_rad: Vector3<f64>) -> Self {
        Self { position_m, euler_rad }
    }

    pub fn rotation(&self) -> Rotation3<f64> {
        Rotation3::from_euler_angles(self.euler_rad.x, self.euler_rad.y, self.euler_rad.z)
    }

    pub fn to_vector(&self) -> Vector6<f64> {
        Vector6::new(self.position_m.x, self.position_m.y, self.position_m.z, self.euler_rad.x, self.euler_rad.y, self.euler_rad.z)
    }

    pub fn from_vector(q: &Vector6<f64>) -> Self {
        Self::new(q.fixed_rows::<3>(0).into(), q.fixed_rows::<3>(3).into())
    }
}

/// ω = E(φ, θ, ψ) (φ̇, θ̇, ψ̇): base-frame angular velocity from Euler rates.
pub fn euler_rate_matrix(euler: &Vector3<f64>) -> Matrix3<f64> {
    let (st, ct) = euler.y.sin_cos();
    let (sp, cp) = euler.z.sin_cos();
    Matrix3::new(cp * ct, -sp, 0.0, sp * ct, cp, 0.0, -st, 0.0, 1.0)
}

/// dE/dt along the Euler rates `rates`.
pub fn euler_rate_matrix_dot(euler: &Vector3<f64>, rates: &Vector3<f64>) -> Matrix3<f64> {
    let (st, ct) = euler.y.sin_cos();
    let (sp, cp) = euler.z.sin_cos();
    let (td, pd) = (rates.y, rates.z);
    Matrix3::new(
        -sp * ct * pd - cp * st * td,
        -cp * pd,
        0.0,
        cp * ct * pd - sp * st * td,
        -sp * pd,
        0.0,
        -ct * td,
        0.0,
        0.0,
    )
}

/// The legs at one pose.
#[derive(Clone, Debug, PartialEq)]
pub struct Legs {
    pub lengths_m: [f64; 6],
    /// From base joint to top joint.
    pub units: [Vector3<f64>; 6],
    /// R a_i: the top joints relative to the platform origin, base axes.
    pub arms: [Vector3<f64>; 6],
}

/// Why a pose or a set of lengths is refused.
#[derive(Clone, Debug, PartialEq)]
pub enum KinematicsError {
    /// Leg `leg` (1-based) would be `length_m`, beyond `limit` = `limit_m`.
    LegLimit { leg: usize, length_m: f64, limit: &'static str, limit_m: f64 },
    /// The Jacobian is (near-)singular; `leg` (1-based) moves most along
    /// the uncontrollable direction.
    Singular { leg: usize, inverse_condition: f64, limit: f64 },
    /// The Jacobian could not be inverted at all (exactly singular).
    SingularJacobian,
    /// Newton–Raphson did not reach `FK_TOLERANCE_M`.
    NoConvergence { iterations: usize, residual_m: f64 },
    /// Two distinct poses near the guess give the same lengths.
    Ambiguous { separation: f64 },
    NotFinite { what: &'static str },
}

impl fmt::Display for KinematicsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::LegLimit { leg, length_m, limit, limit_m } => {
                write!(f, "leg {leg}: length {length_m:.6} m is beyond {limit} = {limit_m} m (outside the workspace; not clamped)")
            }
            Self::Singular { leg, inverse_condition, limit } => write!(
                f,
                "singular configuration: inverse condition number {inverse_condition:.3e} of the Jacobian is below the limit {limit:.0e}; leg {leg} lies most along the lost direction"
            ),
            Self::SingularJacobian => write!(f, "singular configuration: the Jacobian cannot be inverted"),
            Self::NoConvergence { iterations, residual_m } => write!(
                f,
                "forward kinematics did not converge in {iterations} iterations: leg-length residual {residual_m:.3e} m > {FK_TOLERANCE_M:.0e} m; no pose returned"
            ),
            Self::Ambiguous { separation } => {
                write!(f, "forward kinematics is ambiguous: two assemblies {separation:.3e} apart (m or rad) near the guess give the same lengths")
            }
            Self::NotFinite { what } => write!(f, "{what} is not finite"),
        }
    }
}

impl std::error::Error for KinematicsError {}

/// A forward-kinematics answer with its credentials.
#[derive(Clone, Debug, PartialEq)]
pub struct ForwardSolution {
    pub pose: Pose,
    pub iterations: usize,
    pub residual_m: f64,
    /// Newton starts that converged (all to this pose) in the uniqueness check.
    pub starts_agreeing: usize,
}

/// Geometry with its joints worked out.
#[derive(Clone, Debug)]
pub struct Platform {
    pub geometry: Geometry,
    pub joints: Joints,
}

impl Platform {
    /// `geometry` must be valid; the home pose must not be singular.
    pub fn new(geometry: Geometry) -> anyhow::Result<Self> {
        geometry.validate()?;
        let p = Self { joints: geometry.joints(), geometry };
        p.check_singularity(&p.inverse(&p.home()))
            .map_err(|e| anyhow::anyhow!("the joint layout (`top_short_side_angle_deg`, `base_short_side_angle_deg`) is singular at home: {e}"))?;
        Ok(p)
    }

    pub fn paper() -> Self {
        Self::new(Geometry::paper()).expect("the paper's platform is not singular at home")
    }

    pub fn home(&self) -> Pose {
        Pose::new(Vector3::new(0.0, 0.0, self.geometry.home_height_m), Vector3::zeros())
    }

    /// Eq. 2, no limits checked.
    pub fn inverse(&self, pose: &Pose) -> Legs {
        let r = pose.rotation();
        let arms: [Vector3<f64>; 6] = std::array::from_fn(|i| r * self.joints.top[i]);
        let vecs: [Vector3<f64>; 6] = std::array::from_fn(|i| pose.position_m + arms[i] - self.joints.base[i]);
        Legs { lengths_m: vecs.map(|v| v.norm()), units: vecs.map(|v| v.normalize()), arms }
    }

    /// Eq. 2 with the workspace enforced: every length within its limits,
    /// the configuration not singular.
    pub fn inverse_checked(&self, pose: &Pose) -> Result<Legs, KinematicsError> {
        if !pose.to_vector().iter().all(|v| v.is_finite()) {
            return Err(KinematicsError::NotFinite { what: "the pose" });
        }
        let legs = self.inverse(pose);
        self.check_lengths(&legs.lengths_m)?;
        self.check_singularity(&legs)?;
        Ok(legs)
    }

    pub fn check_lengths(&self, lengths_m: &[f64; 6]) -> Result<(), KinematicsError> {
        let g = &self.geometry;
        for (i, &l) in lengths_m.iter().enumerate() {
            if !l.is_finite() {
                return Err(KinematicsError::NotFinite { what: "a leg length" });
            }
            if l < g.leg_min_length_m {
                return Err(KinematicsError::LegLimit { leg: i + 1, length_m: l, limit: "leg_min_length_m", limit_m: g.leg_min_length_m });
            }
            if l > g.leg_max_length_m {
                return Err(KinematicsError::LegLimit { leg: i + 1, length_m: l, limit: "leg_max_length_m", limit_m: g.leg_max_length_m });
            }
        }
        Ok(())
    }

    fn check_singularity(&self, legs: &Legs) -> Result<(), KinematicsError> {
        let mut scaled = twist_jacobian(legs);
        for i in 0..6 {
            for j in 3..6 {
                scaled[(i, j)] /= self.geometry.top_radius_m;
            }
        }
        let svd = scaled.svd(true, false);
        let (lo, hi) = (svd.singular_values.min(), svd.singular_values.max());
        let inverse_condition = if hi > 0.0 { lo / hi } else { 0.0 };
        if inverse_condition >= MIN_INVERSE_CONDITION {
            return Ok(());
        }
        let k = svd.singular_values.imin();
        let u = svd.u.expect("requested");
        let leg = (0..6).max_by(|&a, &b| u[(a, k)].abs().total_cmp(&u[(b, k)].abs())).unwrap_or(0) + 1;
        Err(KinematicsError::Singular { leg, inverse_condition, limit: MIN_INVERSE_CONDITION })
    }

    /// ∂l/∂q at `pose` (Eq. 3 with the Euler-rate map): l̇ = J_q q̇.
    pub fn pose_jacobian(&self, pose: &Pose) -> Matrix6<f64> {
        let legs = self.inverse(pose);
        let mut e = Matrix6::identity();
        e.fixed_view_mut::<3, 3>(3, 3).copy_from(&euler_rate_matrix(&pose.euler_rad));
        twist_jacobian(&legs) * e
    }

    /// Forward kinematics from `guess`, with the uniqueness check: Newton is
    /// restarted from 12 poses around the guess (±5 cm, ±10° along each
    /// axis); every start that converges must land on the same pose.
    pub fn forward(&self, lengths_m: &[f64; 6], guess: &Pose) -> Result<ForwardSolution, KinematicsError> {
        self.check_lengths(lengths_m)?;
        let first = self.newton(lengths_m, guess)?;
        let mut agreeing = 1;
        for axis in 0..6 {
            for sign in [-1.0, 1.0] {
                let mut q = guess.to_vector();
                q[axis] += sign * if axis < 3 { 0.05 } else { 10f64.to_radians() };
                if let Ok(other) = self.newton(lengths_m, &Pose::from_vector(&q)) {
                    let d = (other.pose.to_vector() - first.pose.to_vector()).amax();
                    let near = (other.pose.to_vector() - guess.to_vector()).iter().enumerate().all(|(k, v)| v.abs() <= if k < 3 { 0.2 } else { 0.5 });
                    if d > 1e-9 && near {
                        return Err(KinematicsError::Ambiguous { separation: d });
                    }
                    agreeing += usize::from(d <= 1e-9);
                }
            }
        }
        Ok(ForwardSolution { starts_agreeing: agreeing, ..first })
    }

    /// Plain Newton–Raphson: q ← q − J_q⁻¹ (l(q) − l*).
    pub fn newton(&self, lengths_m: &[f64; 6], guess: &Pose) -> Result<ForwardSolution, KinematicsError> {
        let target = Vector6::from(*lengths_m);
        let mut q = guess.to_vector();
        let mut residual = f64::INFINITY;
        for it in 0..=FK_MAX_ITERATIONS {
            let pose = Pose::from_vector(&q);
            let r = Vector6::from(self.inverse(&pose).lengths_m) - target;
            residual = r.amax();
            if !residual.is_finite() {
                break;
            }
            if residual <= FK_TOLERANCE_M {
                return Ok(ForwardSolution { pose, iterations: it, residual_m: residual, starts_agreeing: 1 });
            }
            let Some(step) = self.pose_jacobian(&pose).lu().solve(&r) else { break };
            q -= step;
        }
        Err(KinematicsError::NoConvergence { iterations: FK_MAX_ITERATIONS, residual_m: residual })
    }
}

/// l̇ = J (v, ω): rows (u_iᵀ, (R a_i × u_i)ᵀ). The paper's Eq. 4 writes the
/// angular part as (u_i × r_ai)ᵀ, which is this with the opposite sign of θ.
pub fn twist_jacobian(legs: &Legs) -> Matrix6<f64> {
    let mut j = Matrix6::zeros();
    for i in 0..6 {
        let u = legs.units[i];
        let m = legs.arms[i].cross(&u);
        for k in 0..3 {
            j[(i, k)] = u[k];
            j[(i, k + 3)] = m[k];
        }
    }
    j
}
