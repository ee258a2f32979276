//! Loading `[plant]` from TOML and refusing values the model cannot run with.
//!
//! Every refusal names the field by its dotted TOML path, e.g.
//! `plant.motor.phase_resistance_ohm: must be > 0`, so a user can find it.

use std::f64::consts::PI;
use std::fmt;
use std::path::Path;

use super::params::PlantParams;

/// A parameter that cannot be used, named by its dotted path in the TOML file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamError {
    pub field: String,
    pub reason: String,
}

impl ParamError {
    fn new(field: &str, reason: impl Into<String>) -> Self {
        Self { field: field.to_string(), reason: reason.into() }
    }
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.field, self.reason)
    }
}

impl std::error::Error for ParamError {}

/// A parameter file that could not be read or used.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadError {
    pub path: String,
    pub error: ParamError,
}

impl fmt::Display for LoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.error)
    }
}

impl std::error::Error for LoadError {}

impl PlantParams {
    /// Reads the `[plant]` table of a rig file (other tables, such as the
    /// controller's `[control]`, are left to their owners) and validates it.
    pub fn load(path: &Path) -> Result<Self, LoadError> {
        let shown = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| LoadError {
            path: shown.clone(),
            error: ParamError::new("plant", format!("cannot read the file: {e}")),
        })?;
        Self::from_toml_str(&text).map_err(|error| LoadError { path: shown, error })
    }

    /// Parses a whole rig file's text; only its `[plant]` table is used.
    pub fn from_toml_str(text: &str) -> Result<Self, ParamError> {
        let doc: toml::Table = toml::from_str(text)
            .map_err(|e| ParamError::new("plant", format!("not valid TOML: {}", e.message())))?;
        let plant = doc
            .get("plant")
            .cloned()
            .ok_or_else(|| ParamError::new("plant", "missing table [plant]"))?;
        let params: PlantParams = serde_path_to_error::deserialize(plant).map_err(|e| {
            let path = e.path().to_string();
            let field = if path == "." || path.is_empty() { "plant".to_string() } else { format!("plant.{path}") };
            ParamError { field, reason: e.into_inner().to_string() }
        })?;
        params.validate()?;
        Ok(params)
    }

    /// Refuses missing-in-spirit (non-finite), negative, zero-where-impossible
    /// and inconsistent values, and a step too long for the stiffest dynamics.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.validate_fields()?;
        self.check_step_resolves_dynamics()
    }

    /// Every field against its own bound, before the step rule: a value
    /// off by a unit is named as itself, not as the stiff rate it makes.
    pub fn validate_fields(&self) -> Result<(), ParamError> {
        let m = &self.motor;
        if m.pole_pairs == 0 {
            return Err(ParamError::new("plant.motor.pole_pairs", "must be >= 1"));
        }
        positive("plant.motor.phase_resistance_ohm", m.phase_resistance_ohm)?;
        positive("plant.motor.inductance_d_h", m.inductance_d_h)?;
        positive("plant.motor.inductance_q_h", m.inductance_q_h)?;
        positive("plant.motor.flux_linkage_wb", m.flux_linkage_wb)?;
        positive("plant.motor.rotor_inertia_kg_m2", m.rotor_inertia_kg_m2)?;
        non_negative("plant.motor.viscous_friction_n_m_s_rad", m.viscous_friction_n_m_s_rad)?;

        positive("plant.inverter.nominal_bus_voltage_v", self.inverter.nominal_bus_voltage_v)?;
        positive("plant.inverter.rated_bus_max_v", self.inverter.rated_bus_max_v)?;
        positive("plant.inverter.rated_current_max_a", self.inverter.rated_current_max_a)?;
        positive("plant.inverter.rated_overcurrent_trip_a", self.inverter.rated_overcurrent_trip_a)?;

        let c = &self.coupling;
        non_negative("plant.coupling.inertia_kg_m2", c.inertia_kg_m2)?;
        positive("plant.coupling.torsional_stiffness_n_m_rad", c.torsional_stiffness_n_m_rad)?;
        non_negative("plant.coupling.torsional_damping_n_m_s_rad", c.torsional_damping_n_m_s_rad)?;

        let s = &self.screw;
        positive("plant.screw.lead_m", s.lead_m)?;
        if s.lead_m > LEAD_MAX_M {
            return Err(ParamError::new(
                "plant.screw.lead_m",
                format!("{} m per turn is beyond a ball screw's lead; must be <= {LEAD_MAX_M} m (a value in millimetres?)", s.lead_m),
            ));
        }
        positive("plant.screw.inertia_kg_m2", s.inertia_kg_m2)?;
        non_negative("plant.screw.viscous_friction_n_m_s_rad", s.viscous_friction_n_m_s_rad)?;
        positive("plant.screw.efficiency", s.efficiency)?;
        if s.efficiency > 1.0 {
            return Err(ParamError::new("plant.screw.efficiency", "must be <= 1"));
        }
        if s.efficiency <= 0.5 {
            // μ = (1−η)/η ≥ 1 would make the screw self-locking, which a ball
            // screw is not; the friction model assumes back-drivability.
            return Err(ParamError::new(
                "plant.screw.efficiency",
                format!(
                    "{} makes the screw self-locking (back-drive efficiency 2 − 1/η = {:.3} <= 0); must be > 0.5",
                    s.efficiency,
                    2.0 - 1.0 / s.efficiency
                ),
            ));
        }
        finite("plant.screw.lead_error_m_per_m", s.lead_error_m_per_m)?;
        if s.lead_error_m_per_m.abs() > LEAD_ERROR_MAX {
            return Err(ParamError::new(
                "plant.screw.lead_error_m_per_m",
                format!(
                    "{:e} is beyond ±{LEAD_ERROR_MAX:e} (±300 µm over 300 mm, the loosest transport grade C10 is ±210 µm)",
                    s.lead_error_m_per_m
                ),
            ));
        }
        non_negative("plant.screw.preload_drag_torque_n_m", s.preload_drag_torque_n_m)?;
        non_negative("plant.screw.nut_distance_at_zero_m", s.nut_distance_at_zero_m)?;

        let r = &self.rod;
        positive("plant.rod.nut_rod_mass_kg", r.nut_rod_mass_kg)?;
        non_negative("plant.rod.payload_mass_kg", r.payload_mass_kg)?;
        non_negative("plant.rod.viscous_friction_n_s_m", r.viscous_friction_n_s_m)?;
        non_negative("plant.rod.coulomb_friction_n", r.coulomb_friction_n)?;
        non_negative("plant.rod.static_friction_n", r.static_friction_n)?;
        if r.static_friction_n < r.coulomb_friction_n {
            return Err(ParamError::new("plant.rod.static_friction_n", "must be >= coulomb_friction_n"));
        }
        positive("plant.rod.stribeck_velocity_m_s", r.stribeck_velocity_m_s)?;

        let l = &self.load;
        non_negative("plant.load.gravity_m_s2", l.gravity_m_s2)?;
        finite("plant.load.initial_tilt_deg", l.initial_tilt_deg)?;
        finite("plant.load.initial_external_force_n", l.initial_external_force_n)?;

        let st = &self.stroke;
        finite("plant.stroke.initial_position_m", st.initial_position_m)?;
        finite("plant.stroke.retracted_stop_m", st.retracted_stop_m)?;
        finite("plant.stroke.extended_stop_m", st.extended_stop_m)?;
        if st.extended_stop_m <= st.retracted_stop_m {
            return Err(ParamError::new("plant.stroke.extended_stop_m", "must exceed retracted_stop_m"));
        }
        if st.initial_position_m <= st.retracted_stop_m || st.initial_position_m >= st.extended_stop_m {
            return Err(ParamError::new("plant.stroke.initial_position_m", "must lie between the end stops"));
        }
        positive("plant.stroke.stop_stiffness_n_m", st.stop_stiffness_n_m)?;
        non_negative("plant.stroke.stop_damping_n_s_m", st.stop_damping_n_s_m)?;

        let d = &self.deformation;
        non_negative("plant.deformation.axial_damping_n_s_m", d.axial_damping_n_s_m)?;
        positive("plant.deformation.contact.coefficient_m_per_n2_3", d.contact.coefficient_m_per_n2_3)?;
        // Preload keeps the contact stiffness finite at zero force.
        positive("plant.deformation.contact.preload_n", d.contact.preload_n)?;
        positive("plant.deformation.screw_axial.youngs_modulus_pa", d.screw_axial.youngs_modulus_pa)?;
        positive("plant.deformation.screw_axial.area_m2", d.screw_axial.area_m2)?;
        positive("plant.deformation.rod.youngs_modulus_pa", d.rod.youngs_modulus_pa)?;
        // At least one rod segment has length: the axial spring must never be rigid.
        positive("plant.deformation.rod.segment1_length_m", d.rod.segment1_length_m)?;
        positive("plant.deformation.rod.segment1_area_m2", d.rod.segment1_area_m2)?;
        non_negative("plant.deformation.rod.segment2_length_m", d.rod.segment2_length_m)?;
        positive("plant.deformation.rod.segment2_area_m2", d.rod.segment2_area_m2)?;
        non_negative("plant.deformation.bearing.coefficient_m_per_n_k", d.bearing.coefficient_m_per_n_k)?;
        positive("plant.deformation.bearing.exponent", d.bearing.exponent)?;
        if d.bearing.exponent > 1.0 {
            // Above 1 the compliance would soften faster than linear and the
            // monotone force inversion's bracket would no longer hold.
            return Err(ParamError::new("plant.deformation.bearing.exponent", "must be <= 1"));
        }
        positive("plant.deformation.bearing.preload_n", d.bearing.preload_n)?;
        positive("plant.deformation.torsion.shear_modulus_pa", d.torsion.shear_modulus_pa)?;
        positive("plant.deformation.torsion.screw_polar_moment_m4", d.torsion.screw_polar_moment_m4)?;
        non_negative("plant.deformation.torsion.fixed_end_length_m", d.torsion.fixed_end_length_m)?;
        positive("plant.deformation.torsion.fixed_end_polar_moment_m4", d.torsion.fixed_end_polar_moment_m4)?;

        positive("plant.friction.regularisation_velocity_m_s", self.friction.regularisation_velocity_m_s)?;

        let se = &self.sensors;
        if se.adc_bits == 0 || se.adc_bits > 24 {
            return Err(ParamError::new("plant.sensors.adc_bits", "must be in 1..=24"));
        }
        positive("plant.sensors.current_full_scale_a", se.current_full_scale_a)?;
        non_negative("plant.sensors.current_noise_a", se.current_noise_a)?;
        positive("plant.sensors.bus_voltage_full_scale_v", se.bus_voltage_full_scale_v)?;
        non_negative("plant.sensors.bus_voltage_noise_v", se.bus_voltage_noise_v)?;
        if se.encoder_counts_per_rev == 0 || se.encoder_counts_per_rev > 32_768 {
            // The core unwraps a 16-bit counter: a revolution must fit in half of it.
            return Err(ParamError::new("plant.sensors.encoder_counts_per_rev", "must be in 1..=32768"));
        }
        finite("plant.sensors.encoder_zero_rad", se.encoder_zero_rad)?;
        positive("plant.sensors.linear_scale_resolution_m", se.linear_scale_resolution_m)?;
        non_negative("plant.sensors.load_cell_noise_n", se.load_cell_noise_n)?;

        let it = &self.integration;
        positive("plant.integration.pwm_frequency_hz", it.pwm_frequency_hz)?;
        if it.substeps_per_pwm_period < 1 || it.substeps_per_pwm_period > MAX_MINIMUM_SUBSTEPS {
            return Err(ParamError::new(
                "plant.integration.substeps_per_pwm_period",
                format!("must be in 1..={MAX_MINIMUM_SUBSTEPS} (the plant adds substeps itself where its dynamics need them)"),
            ));
        }

        let b = &self.brake;
        non_negative("plant.brake.holding_torque_n_m", b.holding_torque_n_m)?;
        non_negative("plant.brake.release_time_s", b.release_time_s)?;
        non_negative("plant.brake.engage_time_s", b.engage_time_s)?;
        if b.fitted {
            positive("plant.brake.holding_torque_n_m", b.holding_torque_n_m)?;
            positive("plant.brake.stiffness_n_m_rad", b.stiffness_n_m_rad)?;
        } else {
            non_negative("plant.brake.stiffness_n_m_rad", b.stiffness_n_m_rad)?;
        }
        non_negative("plant.brake.damping_n_m_s_rad", b.damping_n_m_s_rad)?;
        Ok(())
    }

    /// RK4 steps per PWM period the step rule asks for: the fewest that put
    /// every rate of `fastest_rates_per_s` within its `step_limit`.
    pub fn substeps_needed(&self) -> u32 {
        let f_pwm = self.integration.pwm_frequency_hz;
        let mut n = 1.0f64;
        for (name, rate) in self.fastest_rates_per_s() {
            // A non-finite rate is refused by `validate`; here it asks nothing.
            if rate.is_finite() {
                n = n.max((rate / (step_limit(name) * f_pwm)).ceil());
            }
        }
        n.min(f64::from(u32::MAX)) as u32
    }

    /// The fastest rates of the model (1/s), by name. RK4 is stable to
    /// |λ·h| ≈ 2.785 on the negative real axis. Oscillatory modes (and the
    /// electrical pole) must have |λ·h| ≤ 1 so they are also accurate; a
    /// purely dissipative relaxation (damping, friction regularisation) only
    /// |λ·h| ≤ 2.5 (`step_limit`): RK4's amplification 1 + z + … + z⁴/24
    /// has no real root, so such a transient decays monotonically (by 0.65
    /// per step at 2.5, 10 % inside the stability bound) and its end point
    /// (the steady force) is exact. The load-dependent rates are taken at
    /// three times the full weight, so at working loads they sit well
    /// below their limit.
    pub fn fastest_rates_per_s(&self) -> Vec<(&'static str, f64)> {
        let r = self.metres_per_rad();
        let m = self.moving_mass_kg();
        let j_m = self.motor_side_inertia_kg_m2();
        let j_s = self.screw.inertia_kg_m2;
        let d = &self.deformation;
        let mu = (1.0 - self.screw.efficiency) / self.screw.efficiency;
        // A generous axial force for the load-dependent terms: three times the
        // full weight (an end-of-stroke deceleration on top of gravity).
        let f_ref = 3.0 * m * self.load.gravity_m_s2.max(1.0);
        // Stiffest torsional path: nut at the fixed end (x = 0).
        let c_rot = 1.0 / self.coupling.torsional_stiffness_n_m_rad
            + self.screw.nut_distance_at_zero_m / (d.torsion.shear_modulus_pa * d.torsion.screw_polar_moment_m4)
            + d.torsion.fixed_end_length_m / (d.torsion.shear_modulus_pa * d.torsion.fixed_end_polar_moment_m4);
        let inv_j = 1.0 / j_m + 1.0 / j_s;
        // Stiffest axial path: x = 0, at f_ref (preloaded contacts stiffen with load).
        let lin = self.screw.nut_distance_at_zero_m / (d.screw_axial.youngs_modulus_pa * d.screw_axial.area_m2)
            + d.rod.segment1_length_m / (d.rod.youngs_modulus_pa * d.rod.segment1_area_m2)
            + d.rod.segment2_length_m / (d.rod.youngs_modulus_pa * d.rod.segment2_area_m2);
        let contact = 2.0 / 3.0 * d.contact.coefficient_m_per_n2_3 * (f_ref + d.contact.preload_n).powf(-1.0 / 3.0);
        let bearing = d.bearing.exponent
            * d.bearing.coefficient_m_per_n_k
            * (f_ref + d.bearing.preload_n).powf(d.bearing.exponent - 1.0);
        let k_ax = 1.0 / (lin + contact + bearing);
        let inv_m_ax = 1.0 / m + r * r / j_s;
        let w_eps = self.friction.regularisation_velocity_m_s / r;
        let screw_coulomb = self.screw.preload_drag_torque_n_m + r * mu * f_ref;
        let l_min = self.motor.inductance_d_h.min(self.motor.inductance_q_h);
        vec![
            ("electrical R/L", self.motor.phase_resistance_ohm / l_min),
            ("torsional mode", (inv_j / c_rot).sqrt()),
            ("torsional damping", self.coupling.torsional_damping_n_m_s_rad * inv_j),
            ("axial mode", (k_ax * inv_m_ax).sqrt()),
            ("axial damping", d.axial_damping_n_s_m * inv_m_ax),
            ("end-stop contact", (self.stroke.stop_stiffness_n_m / m).sqrt() + self.stroke.stop_damping_n_s_m / m),
            (
                "rod friction regularisation",
                (self.rod.static_friction_n / self.friction.regularisation_velocity_m_s + self.rod.viscous_friction_n_s_m)
                    / m,
            ),
            (
                "screw friction regularisation",
                (screw_coulomb / w_eps + self.screw.viscous_friction_n_m_s_rad) / j_s,
            ),
        ]
    }

    /// Refuses a rig whose fastest dynamics would need more than
    /// `MAX_SUBSTEPS` RK4 steps per PWM period, naming the field that
    /// makes the rate so fast.
    pub fn check_step_resolves_dynamics(&self) -> Result<(), ParamError> {
        let f_pwm = self.integration.pwm_frequency_hz;
        for (name, rate) in self.fastest_rates_per_s() {
            if !rate.is_finite() {
                return Err(ParamError::new(rate_field(self, name), format!("makes the {name} rate non-finite")));
            }
            let limit = step_limit(name);
            let needed = (rate / (limit * f_pwm)).ceil();
            if needed > f64::from(MAX_SUBSTEPS) {
                return Err(ParamError::new(
                    rate_field(self, name),
                    format!(
                        "makes the {name} rate {rate:.3e} 1/s, which needs {needed} RK4 substeps per PWM period \
                         (rate·step <= {limit}); the plant takes at most {MAX_SUBSTEPS}, i.e. the rate must be <= {:.3e} 1/s",
                        limit * f_pwm * f64::from(MAX_SUBSTEPS)
                    ),
                ));
            }
        }
        Ok(())
    }
}

/// Most RK4 steps per PWM period the step rule may ask for. Beyond it a
/// second of simulated time costs minutes: a rig that needs more has a
/// value far outside any real cylinder's (a regularisation velocity
/// thousands of times below the Stribeck velocity, a bumper of steel).
pub const MAX_SUBSTEPS: u32 = 64;

/// The longest lead a ball screw is made with, m per turn (large-lead
/// screws reach about 80 mm).
pub const LEAD_MAX_M: f64 = 0.1;

/// Largest minimum a rig file may ask for itself (convergence studies).
pub const MAX_MINIMUM_SUBSTEPS: u32 = 1024;

/// Largest |cumulative lead error| a rig file may state: ±300 µm over
/// 300 mm, beyond the loosest transport grade (C10, ±210 µm / 300 mm).
pub const LEAD_ERROR_MAX: f64 = 1.0e-3;

/// The rig-file field that governs a rate of `fastest_rates_per_s`.
fn rate_field(p: &PlantParams, name: &str) -> &'static str {
    match name {
        "electrical R/L" if p.motor.inductance_d_h <= p.motor.inductance_q_h => "plant.motor.inductance_d_h",
        "electrical R/L" => "plant.motor.inductance_q_h",
        "torsional mode" => "plant.coupling.torsional_stiffness_n_m_rad",
        "torsional damping" => "plant.coupling.torsional_damping_n_m_s_rad",
        "axial mode" => "plant.deformation",
        "axial damping" => "plant.deformation.axial_damping_n_s_m",
        "end-stop contact" => "plant.stroke.stop_stiffness_n_m",
        _ => "plant.friction.regularisation_velocity_m_s",
    }
}

/// Largest |λ·h| allowed for a rate of `fastest_rates_per_s`: 2.5 for the
/// dissipative relaxations, 1 for everything else.
pub fn step_limit(name: &str) -> f64 {
    if name.ends_with("damping") || name.ends_with("regularisation") { 2.5 } else { 1.0 }
}

/// Degrees to radians, for the TOML's human-friendly tilt.
pub fn deg_to_rad(deg: f64) -> f64 {
    deg * PI / 180.0
}

fn finite(field: &str, v: f64) -> Result<(), ParamError> {
    if v.is_finite() { Ok(()) } else { Err(ParamError::new(field, "must be finite")) }
}

fn positive(field: &str, v: f64) -> Result<(), ParamError> {
    finite(field, v)?;
    if v > 0.0 { Ok(()) } else { Err(ParamError::new(field, "must be > 0")) }
}

fn non_negative(field: &str, v: f64) -> Result<(), ParamError> {
    finite(field, v)?;
    if v >= 0.0 { Ok(()) } else { Err(ParamError::new(field, "must be >= 0")) }
}
