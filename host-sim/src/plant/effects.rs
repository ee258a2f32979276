//! Unmodelled effects a real rig may have and the nominal model lacks: the
//! hooks that turn the nominal plant into a "truth" rig for the diagnosis
//! suite. Default: none, and the plant is then bit-identical to the
//! nominal one (every hook is behind a test of its own parameter, so the
//! nominal arithmetic is not even touched).
//!
//! Each effect sits where it physically acts:
//!
//! | effect | where | law |
//! |---|---|---|
//! | asymmetric Coulomb / viscous friction | screw–nut, on the screw's rotation | `c₊ s₊ + c₋ s₋ + b₊ ω₊ + b₋ ω₋`, `s = tanh(ω/ω_ε)` |
//! | Stribeck | screw–nut | `T_s e^{−(ω/ω_s)²} s` |
//! | backlash (lost motion) | nut: a dead zone of width `b` in the axial spring | `F = F_spring(δ ∓ b/2)` outside the gap, 0 inside |
//! | position-dependent screw stiffness | screw axial compliance per metre of loaded length | `1/(E_s A_s) + c` (δ2 gains `c F x`) |
//! | Hertz contact | ball–raceway law δ1 | coefficient `C + ΔC` |
//! | coupling torsional compliance | coupling | `1/K_co + c` |
//! | lead error, cumulative and once per revolution | screw thread: nut position of the screw angle | `x_s = x0 + r θ_s (1 + ε) + a sin θ_s + b cos θ_s` |
//! | thermal expansion | the same thread, lead growing with the warm-up | `ε(t) += κ (t − t₀)` |
//! | cogging | rotor | load torque `a sin nθ_m + b cos nθ_m` |
//! | inverter dead time | each inverter leg | phase voltage `− V_dt tanh(i_x/i_ε)`, `V_dt = t_dt f_pwm V_bus` |
//! | current-sensor gain and offset | phase-current sensing | `i_meas = (1 + g) i + o_abc` (`o_abc`: inverse Clarke of `(o_α, o_β)`) |
//! | encoder eccentricity | encoder reading | `θ_meas = θ + e_s sin θ + e_c cos θ` |
//! | external load offset / disturbance | rod, unmeasured | `ΔF + A sin(2π f t)`, or `ΔF + A Σ pulses(t)` |
//!
//! The lead error changes the screw's transmission ratio `dx_s/dθ_s` too;
//! by virtual work the nut force reaches the screw as `(dx_s/dθ_s) F`, so
//! the model stays energy-consistent.

use super::frames;
use super::params::PlantParams;

/// The effects and their parameters. All zero: none (the nominal rig).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct UnmodelledEffects {
    /// Extra screw–nut Coulomb torque moving positive / negative, N·m (≥ 0
    /// opposes the motion).
    pub coulomb_pos_n_m: f64,
    pub coulomb_neg_n_m: f64,
    /// Extra viscous friction moving positive / negative, N·m·s/rad.
    pub viscous_pos_n_m_s_rad: f64,
    pub viscous_neg_n_m_s_rad: f64,
    /// Extra breakaway torque fading with speed, N·m, and its speed, rad/s.
    pub stribeck_torque_n_m: f64,
    pub stribeck_speed_rad_s: f64,
    /// Total axial lost motion in the nut, m.
    pub backlash_m: f64,
    /// Extra axial compliance of the screw per metre of loaded length, m/(N·m).
    pub screw_compliance_m_per_n_m: f64,
    /// Extra Hertz contact coefficient (same law as δ1), m/N^(2/3).
    pub contact_coefficient_m_per_n2_3: f64,
    /// Extra coupling torsional compliance, rad/(N·m).
    pub coupling_compliance_rad_per_n_m: f64,
    /// Cumulative lead error ε: the nut travels `(1 + ε)` times the nominal
    /// lead per revolution.
    pub lead_error_m_per_m: f64,
    /// Once-per-revolution lead error `a sin θ_s + b cos θ_s`, m.
    pub lead_sin_m: f64,
    pub lead_cos_m: f64,
    /// Thermal expansion of the screw: strain rate κ (1/s) from `thermal_start_s`.
    pub thermal_strain_per_s: f64,
    pub thermal_start_s: f64,
    /// Cogging `a sin nθ + b cos nθ` (N·m) with n periods per revolution.
    pub cogging_sin_n_m: f64,
    pub cogging_cos_n_m: f64,
    pub cogging_periods_per_rev: f64,
    /// Inverter dead time, s (with the switching frequency and bus voltage
    /// it is a per-phase voltage error).
    pub dead_time_s: f64,
    /// Current-sensor gain error g and offsets in αβ, A.
    pub current_gain_error: f64,
    pub current_offset_alpha_a: f64,
    pub current_offset_beta_a: f64,
    /// Encoder eccentricity: `θ_meas = θ + e_s sin θ + e_c cos θ`, rad.
    pub encoder_ecc_sin_rad: f64,
    pub encoder_ecc_cos_rad: f64,
    /// Unmeasured axial force on the rod (positive opposes extension), N,
    /// plus a sinusoidal disturbance of amplitude A (N) at f (Hz).
    pub load_offset_n: f64,
    pub load_disturbance_n: f64,
    pub load_disturbance_hz: f64,
    /// Instead of the sinusoid: an unmeasured force with its own time
    /// course, `A × Σ level_k` over the pulses `[start_s, duration_s,
    /// level_k]` active at t (plant time) — steps (long pulses) and short
    /// repeated events. Used only when `load_disturbance_n` ≠ 0.
    pub load_pulses: Vec<[f64; 3]>,
}

/// Phase current below which the dead-time error fades (`tanh(i/i_ε)`):
/// smooth for RK4 (`V_dt/i_ε` over `L`, ≈ 2.7e4 1/s at 1 µs of dead time,
/// is 0.7 per 25 µs step, inside its stability region), and small against
/// the running current.
pub const DEAD_TIME_CURRENT_A: f64 = 0.1;

impl UnmodelledEffects {
    /// No effect at all.
    pub fn is_none(&self) -> bool {
        *self == Self::default()
    }

    /// The effects that are a change of an existing parameter (screw axial
    /// compliance, Hertz coefficient, coupling compliance), applied to the
    /// plant's parameter set. Zero parameters leave it untouched.
    pub fn apply_to_params(&self, p: &mut PlantParams) {
        if self.screw_compliance_m_per_n_m != 0.0 {
            let s = &mut p.deformation.screw_axial;
            let c = 1.0 / (s.youngs_modulus_pa * s.area_m2) + self.screw_compliance_m_per_n_m;
            s.youngs_modulus_pa = 1.0 / (c * s.area_m2);
        }
        if self.contact_coefficient_m_per_n2_3 != 0.0 {
            p.deformation.contact.coefficient_m_per_n2_3 += self.contact_coefficient_m_per_n2_3;
        }
        if self.coupling_compliance_rad_per_n_m != 0.0 {
            let k = &mut p.coupling.torsional_stiffness_n_m_rad;
            *k = 1.0 / (1.0 / *k + self.coupling_compliance_rad_per_n_m);
        }
    }

    /// The effects the right-hand side evaluates, prepared for the model.
    pub fn dynamics(&self, p: &PlantParams) -> EffectDynamics {
        let r = p.metres_per_rad();
        EffectDynamics {
            friction: [self.coulomb_pos_n_m, self.coulomb_neg_n_m, self.viscous_pos_n_m_s_rad, self.viscous_neg_n_m_s_rad]
                .iter()
                .any(|v| *v != 0.0)
                || self.stribeck_torque_n_m != 0.0,
            coulomb: [self.coulomb_pos_n_m, self.coulomb_neg_n_m],
            viscous: [self.viscous_pos_n_m_s_rad, self.viscous_neg_n_m_s_rad],
            stribeck_torque: self.stribeck_torque_n_m,
            inv_stribeck_speed: if self.stribeck_speed_rad_s > 0.0 { 1.0 / self.stribeck_speed_rad_s } else { 0.0 },
            inv_omega_eps: r / p.friction.regularisation_velocity_m_s,
            half_gap: 0.5 * self.backlash_m,
            lead: self.lead_error_m_per_m != 0.0 || self.lead_sin_m != 0.0 || self.lead_cos_m != 0.0 || self.thermal_strain_per_s != 0.0,
            lead_error: self.lead_error_m_per_m,
            lead_sin: self.lead_sin_m,
            lead_cos: self.lead_cos_m,
            thermal_strain: 0.0,
            cogging: [self.cogging_sin_n_m, self.cogging_cos_n_m],
            cogging_n: self.cogging_periods_per_rev,
            dead_time_v_per_bus_v: self.dead_time_s * p.integration.pwm_frequency_hz,
            load_offset: self.load_offset_n,
        }
    }

    /// Thermal strain at time `t` (0 before the warm-up starts).
    pub fn thermal_strain(&self, t: f64) -> f64 {
        self.thermal_strain_per_s * (t - self.thermal_start_s).max(0.0)
    }

    /// The time-varying part of the unmeasured load at `t`, N.
    pub fn load_disturbance(&self, t: f64) -> f64 {
        if self.load_disturbance_n == 0.0 {
            return 0.0;
        }
        if !self.load_pulses.is_empty() {
            let on = |p: &[f64; 3]| t >= p[0] && t < p[0] + p[1];
            return self.load_disturbance_n * self.load_pulses.iter().filter(|p| on(p)).map(|p| p[2]).sum::<f64>();
        }
        self.load_disturbance_n * (std::f64::consts::TAU * self.load_disturbance_hz * t).sin()
    }

    /// What the current sensors see for true phase currents `i`.
    pub fn sensed_currents(&self, i: [f64; 3]) -> [f64; 3] {
        if self.current_gain_error == 0.0 && self.current_offset_alpha_a == 0.0 && self.current_offset_beta_a == 0.0 {
            return i;
        }
        let o = frames::inverse_clarke(self.current_offset_alpha_a, self.current_offset_beta_a);
        std::array::from_fn(|k| (1.0 + self.current_gain_error) * i[k] + o[k])
    }

    /// What the encoder reads at true rotor angle `θ`.
    pub fn encoder_angle(&self, theta: f64) -> f64 {
        if self.encoder_ecc_sin_rad == 0.0 && self.encoder_ecc_cos_rad == 0.0 {
            return theta;
        }
        let (s, c) = theta.sin_cos();
        theta + self.encoder_ecc_sin_rad * s + self.encoder_ecc_cos_rad * c
    }
}

/// The parts of the effects that enter the right-hand side, with a flag per
/// group so the nominal path skips them.
#[derive(Clone, Copy, Debug, Default)]
pub struct EffectDynamics {
    friction: bool,
    coulomb: [f64; 2],
    viscous: [f64; 2],
    stribeck_torque: f64,
    inv_stribeck_speed: f64,
    inv_omega_eps: f64,
    half_gap: f64,
    lead: bool,
    lead_error: f64,
    lead_sin: f64,
    lead_cos: f64,
    /// Present thermal strain, set by the plant before each period (it
    /// changes over seconds, so holding it through a period is exact enough).
    pub thermal_strain: f64,
    cogging: [f64; 2],
    cogging_n: f64,
    dead_time_v_per_bus_v: f64,
    /// Unmeasured load (offset + present disturbance), N; set by the plant.
    pub load_offset: f64,
}

impl EffectDynamics {
    /// Extra screw friction torque at screw speed `ω_s` (sign of the motion).
    #[inline]
    pub fn screw_friction_n_m(&self, omega_s: f64) -> f64 {
        if !self.friction {
            return 0.0;
        }
        let s = (omega_s * self.inv_omega_eps).tanh();
        let w = omega_s * self.inv_stribeck_speed;
        self.coulomb[0] * s.max(0.0)
            + self.coulomb[1] * s.min(0.0)
            + self.viscous[0] * omega_s.max(0.0)
            + self.viscous[1] * omega_s.min(0.0)
            + self.stribeck_torque * (-w * w).exp() * s
    }

    /// Lost motion: the spring deflection left after the gap is taken up.
    /// `None` inside the gap (no contact, no force).
    #[inline]
    pub fn engaged_deflection(&self, deflection_m: f64) -> Option<f64> {
        if self.half_gap == 0.0 {
            return Some(deflection_m);
        }
        let d = deflection_m.abs() - self.half_gap;
        (d > 0.0).then(|| d.copysign(deflection_m))
    }

    /// Whether there is a gap.
    #[inline]
    pub fn has_gap(&self) -> bool {
        self.half_gap > 0.0
    }

    /// With a gap, the flank can only push: spring + damper force keeps the
    /// spring's sign (the damper does not pull the flanks together), and is
    /// zero out of contact.
    #[inline]
    pub fn contact_force(&self, spring_n: f64, total_n: f64) -> f64 {
        if spring_n > 0.0 {
            total_n.max(0.0)
        } else if spring_n < 0.0 {
            total_n.min(0.0)
        } else {
            0.0
        }
    }

    /// Where the rod rests in the gap under a steady force: on the flank the
    /// force pushes it against, half the gap behind the screw.
    pub fn gap_offset_m(&self, force_n: f64) -> f64 {
        if self.half_gap == 0.0 || force_n == 0.0 {
            return 0.0;
        }
        self.half_gap.copysign(force_n)
    }

    /// Nut position of the screw angle and its slope `dx_s/dθ_s`, given the
    /// nominal `x0 + r θ_s` and `r`.
    #[inline]
    pub fn thread(&self, nominal_m: f64, r: f64, theta_s: f64) -> (f64, f64) {
        if !self.lead {
            return (nominal_m, r);
        }
        let eps = self.lead_error + self.thermal_strain;
        let (s, c) = theta_s.sin_cos();
        (
            nominal_m + eps * r * theta_s + self.lead_sin * s + self.lead_cos * c,
            r * (1.0 + eps) + self.lead_sin * c - self.lead_cos * s,
        )
    }

    /// Cogging torque at rotor angle `θ_m`, acting against the motor torque.
    #[inline]
    pub fn cogging_n_m(&self, theta_m: f64) -> f64 {
        if self.cogging == [0.0, 0.0] {
            return 0.0;
        }
        let (s, c) = (self.cogging_n * theta_m).sin_cos();
        self.cogging[0] * s + self.cogging[1] * c
    }

    /// Phase voltages after the dead time: each leg loses `V_dt` against
    /// its current (the voltage sum stays zero after the star point floats).
    #[inline]
    pub fn dead_time(&self, u: [f64; 3], i_d: f64, i_q: f64, sin_e: f64, cos_e: f64, bus_v: f64) -> [f64; 3] {
        if self.dead_time_v_per_bus_v == 0.0 {
            return u;
        }
        let i_abc = frames::dq_to_abc(i_d, i_q, sin_e, cos_e);
        let v = self.dead_time_v_per_bus_v * bus_v;
        let drop: [f64; 3] = std::array::from_fn(|k| v * (i_abc[k] / DEAD_TIME_CURRENT_A).tanh());
        let mean = (drop[0] + drop[1] + drop[2]) / 3.0;
        std::array::from_fn(|k| u[k] - (drop[k] - mean))
    }
}
