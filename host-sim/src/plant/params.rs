//! The rig as the plant model sees it: one struct per `[plant.*]` TOML table.
//!
//! This is a separate parameter set from the controller's `ControlParams`: the
//! nominal rig reproduces what the controller believes, a "truth" rig may
//! differ. `Default` is the nominal rig and must equal `params/rig.toml`
//! (a test checks it). The reasoning behind every value lives in the TOML
//! comments and `docs/plant.md`; here are only the units and meanings.

use serde::{Deserialize, Serialize};

/// PMSM (paper Eqs. 7–10, 17).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorParams {
    pub pole_pairs: u32,
    /// Phase (line-to-neutral) resistance `R_s`.
    pub phase_resistance_ohm: f64,
    pub inductance_d_h: f64,
    pub inductance_q_h: f64,
    /// Permanent-magnet flux linkage `ψ_f` (peak, per phase).
    pub flux_linkage_wb: f64,
    pub rotor_inertia_kg_m2: f64,
    /// Bearing and windage drag on the rotor `B_m`.
    pub viscous_friction_n_m_s_rad: f64,
}

/// Averaged inverter.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InverterParams {
    /// Bus voltage reported before the first `advance` tells the real one.
    pub nominal_bus_voltage_v: f64,
    /// The simulated power stage's rating, which the simulated drive holds
    /// parameter sets to with the board's check (`PowerStageRating`): the
    /// highest bus voltage, continuous phase current and overcurrent trip.
    pub rated_bus_max_v: f64,
    pub rated_current_max_a: f64,
    pub rated_overcurrent_trip_a: f64,
}

impl InverterParams {
    /// The rating as the core's check takes it.
    pub fn rating(&self) -> servo_core::params::PowerStageRating {
        servo_core::params::PowerStageRating {
            bus_max_v: self.rated_bus_max_v as f32,
            current_max_a: self.rated_current_max_a as f32,
            overcurrent_trip_max_a: self.rated_overcurrent_trip_a as f32,
        }
    }
}

/// Coupling between rotor and screw (Eq. 11 plus damping).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CouplingParams {
    /// Lumped with the rotor.
    pub inertia_kg_m2: f64,
    /// `K_co`; in series with the screw torsion of `deformation.torsion`.
    pub torsional_stiffness_n_m_rad: f64,
    /// Damping across the whole rotor-to-nut torsional path.
    pub torsional_damping_n_m_s_rad: f64,
}

/// Ball screw and nut (Eqs. 12–14).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScrewParams {
    /// Lead `L_s`: nut travel per screw revolution.
    pub lead_m: f64,
    /// Cumulative lead error ε: the nut travels `(1 + ε) L_s` per screw
    /// revolution while the drive believes `L_s` (a screw's accuracy grade:
    /// C7 allows ±52 µm over 300 mm, |ε| ≤ 1.7e-4). Absent: 0.
    #[serde(default)]
    pub lead_error_m_per_m: f64,
    pub inertia_kg_m2: f64,
    /// Support-bearing drag `B_s`.
    pub viscous_friction_n_m_s_rad: f64,
    /// Forward efficiency `η_s`; becomes Coulomb friction `μ = (1−η)/η` of
    /// the transmitted axial force.
    pub efficiency: f64,
    /// Load-independent Coulomb drag torque of the preloaded nut.
    pub preload_drag_torque_n_m: f64,
    /// Threaded length between the fixed-end bearing and the nut at x = 0;
    /// the loaded length in δ2 and δ5 is this plus x.
    pub nut_distance_at_zero_m: f64,
}

/// Nut, piston rod and payload: one rigid translating mass (Eq. 15).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RodParams {
    pub nut_rod_mass_kg: f64,
    /// Carried beyond the load cell; its weight is the axial gravity load.
    pub payload_mass_kg: f64,
    /// Seal and guide friction: `B_n v + [F_c + (F_s − F_c) e^{−(v/v_s)²}] tanh(v/v_ε)`.
    pub viscous_friction_n_s_m: f64,
    pub coulomb_friction_n: f64,
    pub static_friction_n: f64,
    pub stribeck_velocity_m_s: f64,
}

/// External axial load: gravity along the cylinder plus an optional force.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadParams {
    pub gravity_m_s2: f64,
    /// From horizontal; 90° = rod pointing up.
    pub initial_tilt_deg: f64,
    /// Positive opposes extension.
    pub initial_external_force_n: f64,
}

/// Stroke and the hard end stops beyond it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StrokeParams {
    /// Motor-side position at θ_m = 0 (construction).
    pub initial_position_m: f64,
    pub retracted_stop_m: f64,
    pub extended_stop_m: f64,
    pub stop_stiffness_n_m: f64,
    pub stop_damping_n_s_m: f64,
}

/// δ1 (Eq. 21): preloaded Hertz contact `C [(|F| + F_p)^{2/3} − F_p^{2/3}]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactParams {
    pub coefficient_m_per_n2_3: f64,
    pub preload_n: f64,
}

/// δ2 (Eq. 22): `F (l0 + x) / (E_s A_s)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScrewAxialParams {
    pub youngs_modulus_pa: f64,
    pub area_m2: f64,
}

/// δ3 (Eq. 23): two rod segments in series.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RodAxialParams {
    pub youngs_modulus_pa: f64,
    pub segment1_length_m: f64,
    pub segment1_area_m2: f64,
    pub segment2_length_m: f64,
    pub segment2_area_m2: f64,
}

/// δ4 (Eq. 24): preloaded bearing pair `C [(|F| + F_p)^k − F_p^k]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BearingParams {
    pub coefficient_m_per_n_k: f64,
    pub exponent: f64,
    pub preload_n: f64,
}

/// δ5 (Eq. 25): screw twist `T_s (L_s1/(G I_s1) + L_s2/(G I_s2))`, with
/// `L_s1 = l0 + x` the threaded length carrying the torque to the nut.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TorsionParams {
    pub shear_modulus_pa: f64,
    pub screw_polar_moment_m4: f64,
    pub fixed_end_length_m: f64,
    pub fixed_end_polar_moment_m4: f64,
}

/// Rigid–flexible deformation (paper §3), calibrated to its Fig. 5.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeformationParams {
    /// Structural damping in parallel with the axial compliance.
    pub axial_damping_n_s_m: f64,
    pub contact: ContactParams,
    pub screw_axial: ScrewAxialParams,
    pub rod: RodAxialParams,
    pub bearing: BearingParams,
    pub torsion: TorsionParams,
}

/// Shared by every Coulomb term.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionParams {
    /// `v_ε` in `tanh(v/v_ε)`; at the screw it is `ω_ε = 2π v_ε / L_s`.
    pub regularisation_velocity_m_s: f64,
}

/// What the drive measures, and how badly.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorParams {
    pub adc_bits: u32,
    /// Phase-current ADC spans ±this.
    pub current_full_scale_a: f64,
    /// Gaussian σ added before quantisation.
    pub current_noise_a: f64,
    /// Bus ADC spans 0..this.
    pub bus_voltage_full_scale_v: f64,
    pub bus_voltage_noise_v: f64,
    pub encoder_counts_per_rev: u32,
    /// Mechanical angle at which the encoder's count zero sits, rad: the
    /// encoder disc is mounted with no known relation to the magnets.
    /// Absent: 0 (count zero at θ_e = 0).
    #[serde(default)]
    pub encoder_zero_rad: f64,
    pub linear_scale_enabled: bool,
    pub linear_scale_resolution_m: f64,
    pub load_cell_enabled: bool,
    pub load_cell_noise_n: f64,
}

/// Fixed-step RK4.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntegrationParams {
    pub pwm_frequency_hz: f64,
    /// The fewest RK4 steps per PWM period. The plant takes more when its
    /// own step rule asks for them (`PlantParams::substeps`): a rig never
    /// needs this set by hand; a larger value only buys accuracy.
    pub substeps_per_pwm_period: u32,
}

/// The whole `[plant]` table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantParams {
    pub motor: MotorParams,
    pub inverter: InverterParams,
    pub coupling: CouplingParams,
    pub screw: ScrewParams,
    pub rod: RodParams,
    pub load: LoadParams,
    pub stroke: StrokeParams,
    pub deformation: DeformationParams,
    pub friction: FrictionParams,
    pub sensors: SensorParams,
    pub integration: IntegrationParams,
    pub brake: super::brake::BrakeParams,
}

impl Default for PlantParams {
    /// The nominal rig; identical to `params/rig.toml` (see its comments).
    fn default() -> Self {
        Self {
            motor: MotorParams {
                pole_pairs: 4,
                phase_resistance_ohm: 0.12,
                inductance_d_h: 0.35e-3,
                inductance_q_h: 0.35e-3,
                flux_linkage_wb: 0.0175,
                rotor_inertia_kg_m2: 0.30e-4,
                viscous_friction_n_m_s_rad: 0.5e-4,
            },
            inverter: InverterParams { nominal_bus_voltage_v: 48.0, rated_bus_max_v: 60.0, rated_current_max_a: 40.0, rated_overcurrent_trip_a: 45.0 },
            coupling: CouplingParams {
                inertia_kg_m2: 0.02e-4,
                torsional_stiffness_n_m_rad: 6000.0,
                torsional_damping_n_m_s_rad: 0.002,
            },
            screw: ScrewParams {
                lead_m: 0.005,
                lead_error_m_per_m: 0.0,
                inertia_kg_m2: 0.74e-4,
                viscous_friction_n_m_s_rad: 0.5e-4,
                efficiency: 0.9,
                preload_drag_torque_n_m: 0.03,
                nut_distance_at_zero_m: 0.0,
            },
            rod: RodParams {
                nut_rod_mass_kg: 4.2,
                payload_mass_kg: 136.5,
                viscous_friction_n_s_m: 160.0,
                coulomb_friction_n: 30.0,
                static_friction_n: 45.0,
                stribeck_velocity_m_s: 0.003,
            },
            load: LoadParams { gravity_m_s2: 9.81, initial_tilt_deg: 90.0, initial_external_force_n: 0.0 },
            stroke: StrokeParams {
                initial_position_m: 0.0,
                retracted_stop_m: -0.010,
                extended_stop_m: 0.510,
                stop_stiffness_n_m: 2.0e7,
                stop_damping_n_s_m: 2.0e4,
            },
            deformation: DeformationParams {
                axial_damping_n_s_m: 2500.0,
                contact: ContactParams { coefficient_m_per_n2_3: 4.29e-7, preload_n: 500.0 },
                screw_axial: ScrewAxialParams { youngs_modulus_pa: 2.47e10, area_m2: 2.27e-4 },
                rod: RodAxialParams {
                    youngs_modulus_pa: 2.47e10,
                    segment1_length_m: 0.55,
                    segment1_area_m2: 3.52e-4,
                    segment2_length_m: 0.05,
                    segment2_area_m2: 3.14e-4,
                },
                bearing: BearingParams {
                    coefficient_m_per_n_k: 5.97e-7,
                    exponent: 0.6666666666666666,
                    preload_n: 400.0,
                },
                torsion: TorsionParams {
                    shear_modulus_pa: 9.51e9,
                    screw_polar_moment_m4: 8.20e-9,
                    fixed_end_length_m: 0.08,
                    fixed_end_polar_moment_m4: 4.97e-9,
                },
            },
            friction: FrictionParams { regularisation_velocity_m_s: 1.0e-4 },
            sensors: SensorParams {
                adc_bits: 12,
                current_full_scale_a: 50.0,
                current_noise_a: 0.03,
                bus_voltage_full_scale_v: 72.0,
                bus_voltage_noise_v: 0.05,
                encoder_counts_per_rev: 10_000,
                encoder_zero_rad: 0.0,
                linear_scale_enabled: true,
                linear_scale_resolution_m: 1.0e-6,
                load_cell_enabled: true,
                load_cell_noise_n: 2.0,
            },
            integration: IntegrationParams { pwm_frequency_hz: 20_000.0, substeps_per_pwm_period: 1 },
            brake: super::brake::BrakeParams::default(),
        }
    }
}

impl PlantParams {
    /// Nut + rod + payload.
    pub fn moving_mass_kg(&self) -> f64 {
        self.rod.nut_rod_mass_kg + self.rod.payload_mass_kg
    }

    /// Rotor + coupling (the motor side of the torsional spring).
    pub fn motor_side_inertia_kg_m2(&self) -> f64 {
        self.motor.rotor_inertia_kg_m2 + self.coupling.inertia_kg_m2
    }

    /// Metres of nut travel per screw radian, `L_s / 2π`.
    pub fn metres_per_rad(&self) -> f64 {
        self.screw.lead_m / (2.0 * std::f64::consts::PI)
    }

    /// RK4 steps per PWM period the plant takes: the rig file's minimum, or
    /// more if the step rule (`substeps_needed`) asks for them.
    pub fn substeps(&self) -> u32 {
        self.integration.substeps_per_pwm_period.max(self.substeps_needed())
    }

    /// Largest RK4 step: `1 / (f_pwm · substeps())`.
    pub fn max_step_s(&self) -> f64 {
        1.0 / (self.integration.pwm_frequency_hz * f64::from(self.substeps()))
    }
}
