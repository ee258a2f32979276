//! PMSM in the rotor d-q frame (paper Eqs. 7–10, 17), f64.
//!
//! `L_d di_d/dt = u_d − R i_d + p ω_m L_q i_q`
//! `L_q di_q/dt = u_q − R i_q − p ω_m (L_d i_d + ψ_f)`
//! `T_m = 1.5 p [ψ_f i_q + (L_d − L_q) i_d i_q]`
//! The mechanical side (rotor inertia, coupling) lives in `mechanics`.

use super::frames;
use super::params::PlantParams;

#[derive(Clone, Copy, Debug)]
pub struct Motor {
    pub pole_pairs: f64,
    pub resistance_ohm: f64,
    pub l_d_h: f64,
    pub l_q_h: f64,
    pub flux_wb: f64,
    inv_l_d: f64,
    inv_l_q: f64,
}

impl Motor {
    pub fn new(p: &PlantParams) -> Self {
        let m = &p.motor;
        Self {
            pole_pairs: f64::from(m.pole_pairs),
            resistance_ohm: m.phase_resistance_ohm,
            l_d_h: m.inductance_d_h,
            l_q_h: m.inductance_q_h,
            flux_wb: m.flux_linkage_wb,
            inv_l_d: 1.0 / m.inductance_d_h,
            inv_l_q: 1.0 / m.inductance_q_h,
        }
    }

    /// `(di_d/dt, di_q/dt)` for d-q voltages `u` and mechanical speed `ω_m`.
    #[inline]
    pub fn current_derivatives(&self, u_d: f64, u_q: f64, i_d: f64, i_q: f64, omega_m: f64) -> (f64, f64) {
        let w_e = self.pole_pairs * omega_m;
        let did = (u_d - self.resistance_ohm * i_d + w_e * self.l_q_h * i_q) * self.inv_l_d;
        let diq = (u_q - self.resistance_ohm * i_q - w_e * (self.l_d_h * i_d + self.flux_wb)) * self.inv_l_q;
        (did, diq)
    }

    /// Electromagnetic torque `1.5 p [ψ_f i_q + (L_d − L_q) i_d i_q]`.
    #[inline]
    pub fn torque_n_m(&self, i_d: f64, i_q: f64) -> f64 {
        1.5 * self.pole_pairs * (self.flux_wb * i_q + (self.l_d_h - self.l_q_h) * i_d * i_q)
    }

    /// Permanent-magnet back-EMF per phase, `e_a = −ω_e ψ_f sin θ_e`, …
    /// (in d-q it is `(0, ω_e ψ_f)`).
    #[inline]
    pub fn back_emf_abc(&self, omega_m: f64, sin_e: f64, cos_e: f64) -> [f64; 3] {
        frames::dq_to_abc(0.0, self.pole_pairs * omega_m * self.flux_wb, sin_e, cos_e)
    }

    /// Power drawn from the terminals, `1.5 (u_d i_d + u_q i_q)` (the 1.5
    /// because the transforms are amplitude-invariant).
    #[inline]
    pub fn electrical_power_w(u_d: f64, u_q: f64, i_d: f64, i_q: f64) -> f64 {
        1.5 * (u_d * i_d + u_q * i_q)
    }

    /// Magnetic energy `1.5 · ½ (L_d i_d² + L_q i_q²)`.
    pub fn magnetic_energy_j(&self, i_d: f64, i_q: f64) -> f64 {
        0.75 * (self.l_d_h * i_d * i_d + self.l_q_h * i_q * i_q)
    }

    /// Copper loss `1.5 R (i_d² + i_q²)`.
    pub fn copper_loss_w(&self, i_d: f64, i_q: f64) -> f64 {
        1.5 * self.resistance_ohm * (i_d * i_d + i_q * i_q)
    }
}
