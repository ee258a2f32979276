//! Friction laws, smooth so a fixed-step RK4 can integrate them.
//!
//! Every Coulomb term is regularised as `tanh(v / v_ε)` instead of `sign(v)`:
//! the law is smooth, odd and zero at rest, which makes standstill a steep
//! viscous region of slope `F_c / v_ε` rather than true stiction. `v_ε` is
//! chosen so that region is narrow (0.1 mm/s against a 3 mm/s Stribeck
//! velocity) yet slow enough for the step (`params_check` refuses a step that
//! does not resolve it).

use super::params::PlantParams;

/// `tanh`, without the libm call where it is ±1.0 exactly in f64 (|x| > 19.1;
/// 20 to be sure): in motion the regularisation's argument is in the
/// thousands.
#[inline]
fn saturating_tanh(x: f64) -> f64 {
    if x.abs() > 20.0 { 1f64.copysign(x) } else { x.tanh() }
}

/// Nut, rod-seal and guide friction on the translating mass.
#[derive(Clone, Copy, Debug)]
pub struct RodFriction {
    viscous: f64,
    coulomb: f64,
    /// `F_s − F_c`: the extra breakaway force that fades with speed.
    stribeck_excess: f64,
    inv_stribeck_velocity: f64,
    inv_regularisation: f64,
}

impl RodFriction {
    pub fn new(p: &PlantParams) -> Self {
        Self {
            viscous: p.rod.viscous_friction_n_s_m,
            coulomb: p.rod.coulomb_friction_n,
            stribeck_excess: p.rod.static_friction_n - p.rod.coulomb_friction_n,
            inv_stribeck_velocity: 1.0 / p.rod.stribeck_velocity_m_s,
            inv_regularisation: 1.0 / p.friction.regularisation_velocity_m_s,
        }
    }

    /// Friction force opposing rod velocity `v` (returned with the sign of v):
    /// `B v + [F_c + (F_s − F_c) exp(−(v/v_s)²)] tanh(v/v_ε)`.
    #[inline]
    pub fn force_n(&self, v_m_s: f64) -> f64 {
        let s = v_m_s * self.inv_stribeck_velocity;
        // exp(−s²) is exactly 0.0 past s² ≈ 745; skipping the call there
        // gives the same number without libm's slow underflow path.
        let fade = if s * s < 746.0 { (-s * s).exp() } else { 0.0 };
        let magnitude = self.coulomb + self.stribeck_excess * fade;
        self.viscous * v_m_s + magnitude * saturating_tanh(v_m_s * self.inv_regularisation)
    }
}

/// Screw–nut friction acting on the screw's rotation.
///
/// The screw's efficiency η is not a gain on the force: it is the friction
/// of balls sliding on raceways, which is proportional to the normal load and
/// hence to the transmitted axial force. Writing the Coulomb torque as
/// `(L/2π) μ |F|` with `μ = (1 − η)/η` gives, in steady motion:
/// - motor driving the load: `T = (L/2π) F (1 + μ) = (L/2π) F / η`, the
///   forward efficiency η exactly;
/// - load back-driving the motor: `T = (L/2π) F (1 − μ)`, a back-drive
///   efficiency `η' = 1 − μ = 2 − 1/η`, the usual ball-screw catalogue rule.
///
/// One law gives both directions with no switching on "who drives whom",
/// and it is zero at rest, so a held load shows no friction.
#[derive(Clone, Copy, Debug)]
pub struct ScrewFriction {
    viscous: f64,
    preload_drag: f64,
    /// `(L/2π) μ`: Coulomb torque per newton of axial force.
    load_coefficient: f64,
    inv_regularisation: f64,
}

impl ScrewFriction {
    pub fn new(p: &PlantParams) -> Self {
        let r = p.metres_per_rad();
        let eta = p.screw.efficiency;
        Self {
            viscous: p.screw.viscous_friction_n_m_s_rad,
            preload_drag: p.screw.preload_drag_torque_n_m,
            load_coefficient: r * (1.0 - eta) / eta,
            // The same v_ε as the rod, expressed at the screw: ω_ε = v_ε / (L/2π).
            inv_regularisation: r / p.friction.regularisation_velocity_m_s,
        }
    }

    /// `μ = (1 − η)/η`, per unit of lead-scaled force.
    pub fn mu(eta: f64) -> f64 {
        (1.0 - eta) / eta
    }

    /// Friction torque opposing screw speed `ω_s` under axial force `F`.
    #[inline]
    pub fn torque_n_m(&self, omega_s: f64, axial_force_n: f64) -> f64 {
        let coulomb = self.preload_drag + self.load_coefficient * axial_force_n.abs();
        self.viscous * omega_s + coulomb * saturating_tanh(omega_s * self.inv_regularisation)
    }

    /// The Coulomb part alone (no viscous term).
    #[inline]
    pub fn coulomb_torque_n_m(&self, omega_s: f64, axial_force_n: f64) -> f64 {
        (self.preload_drag + self.load_coefficient * axial_force_n.abs()) * (omega_s * self.inv_regularisation).tanh()
    }
}
