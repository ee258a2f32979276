//! Every rate, gain and limit of the drive, in one place.
//!
//! The firmware compiles `ControlParams::DEFAULT`; the simulator reads the same
//! struct from the `[control]` table of its TOML file (feature `serde`), so a
//! gain tuned in simulation is the gain that ships. Defaults derive from the
//! paper's Table 1 (400 W, 3000 rpm, 250 mm/s, 1.38 kN, 500 mm stroke, 5 mm lead)
//! and a 48 V, 4-pole-pair servo motor of that rating; each value says why.

use core::f32::consts::PI;

mod defaults;
pub mod leaves;
pub mod ranges;
mod lifecycle;
mod live;
pub mod rating;
pub mod record;
pub mod stream;
mod validate;
pub mod value;
pub use lifecycle::*;
pub use stream::{StreamParams, LEGS};
pub use value::{Value, ValueKind};
pub use rating::{PowerStageRating, RatingLowered};
pub use validate::{ParamError, ValidatedParams};

use serde::{Deserialize, Serialize};

/// Electrical model of the PMSM as the controller believes it (nameplate).
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct MotorParams {
    /// Pole pairs `p`.
    pub pole_pairs: u32,
    /// Phase (line-to-neutral) resistance `R_s`.
    pub phase_resistance_ohm: f32,
    /// d-axis inductance `L_d`.
    pub inductance_d_h: f32,
    /// q-axis inductance `L_q`.
    pub inductance_q_h: f32,
    /// Permanent-magnet flux linkage `ψ_f` (peak, per phase).
    pub flux_linkage_wb: f32,
}

/// The mechanics as the controller believes them, for feedforward and scaling.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct DriveTrainParams {
    /// Ball-screw lead `L_s`: nut travel per screw revolution.
    pub screw_lead_m: f32,
    /// Forward efficiency `η_s` of the screw-nut pair (motor drives the load).
    pub screw_efficiency: f32,
    /// Rotor + coupling + screw inertia (everything that turns).
    pub rotating_inertia_kg_m2: f32,
    /// Nut + rod + nominal payload mass, reflected through the lead for the
    /// acceleration feedforward.
    pub moving_mass_kg: f32,
    /// Viscous friction seen at the motor shaft, for the speed feedforward.
    pub viscous_friction_n_m_s_rad: f32,
    /// Load-independent Coulomb friction at the motor shaft (nut preload
    /// drag plus the rod seal's Coulomb force through the lead), for the
    /// friction feedforward.
    pub coulomb_friction_n_m: f32,
    /// Reference speed over which the friction feedforward's sign ramps from
    /// 0 to ±1: a hard sign would chatter at standstill.
    pub friction_feedforward_speed_rad_s: f32,
    /// Share of the modelled Coulomb friction fed forward, 0 (off) to 1. On a
    /// new rig start low and raise it while watching the tracking error at
    /// move starts: above the true friction it pushes the rod ahead.
    pub friction_feedforward_gain: f32,
}

/// Loop rates. The current loop runs every PWM period; the outer loops are
/// decimated from it so all three stay phase-locked to the ADC trigger.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct RateParams {
    /// PWM (and current-loop) frequency.
    pub pwm_frequency_hz: f32,
    /// Current-loop periods per speed-loop period (20 kHz / 4 = 5 kHz).
    pub speed_loop_divider: u32,
    /// Current-loop periods per position-loop period (20 kHz / 20 = 1 kHz).
    pub position_loop_divider: u32,
}

/// Gains of one PI regulator.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct PiGains {
    /// Proportional gain (output unit per error unit).
    pub kp: f32,
    /// Integral gain (output unit per error unit per second).
    pub ki: f32,
}

/// Quadrature encoder and its tracking observer (a type-2 PLL).
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct EncoderParams {
    /// Counts per mechanical revolution (lines × 4).
    pub counts_per_rev: u32,
    /// +1 if counts increase with positive (extending) rotation, else −1.
    pub direction: i32,
    /// Electrical angle at encoder count zero, found by alignment.
    pub electrical_offset_rad: f32,
    /// PLL proportional gain (1/s): 2ζω_n with ω_n = 2π·400 Hz, ζ = 1.
    pub pll_kp_per_s: f32,
    /// PLL integral gain (1/s²): ω_n².
    pub pll_ki_per_s2: f32,
}

/// Jerk-limited (S-curve) trajectory limits, at the piston rod.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct TrajectoryParams {
    pub max_velocity_m_s: f32,
    pub max_acceleration_m_s2: f32,
    pub max_jerk_m_s3: f32,
}

/// The paper's Eq. 19 operating limits plus the inverter's.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct LimitParams {
    /// Current circle `i_d² + i_q² ≤ i_s²` (peak phase amplitude).
    pub current_max_a: f32,
    /// Copper loss bound `1.5 R (i_d² + i_q²) ≤ P_cu`.
    pub copper_power_max_w: f32,
    /// `|ω_m| ≤ 2π n_e`.
    pub speed_max_rad_s: f32,
    /// Stroke `0 ≤ x_n ≤ L_n,max`, motor-side position in metres.
    pub stroke_min_m: f32,
    pub stroke_max_m: f32,
    /// Fraction of the linear SVPWM range (V_bus/√3) the current loop may use.
    /// Below 1 so the low-side shunts keep a minimum on-time for sampling.
    pub max_modulation: f32,
}

/// Thresholds that latch a fault (see `protection::faults`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct FaultParams {
    /// Instantaneous phase current trip, checked every PWM period.
    pub overcurrent_trip_a: f32,
    pub bus_overvoltage_v: f32,
    pub bus_undervoltage_v: f32,
    /// Largest believable encoder change in one PWM period, in counts.
    pub encoder_max_step_counts: u32,
    /// Largest believable distance between a new count and the tracking
    /// observer's prediction of it, in counts.
    pub encoder_max_innovation_counts: f32,
    /// Position following error (command − motor-side position) that trips.
    pub position_following_error_m: f32,
    /// Motor-side position beyond the stroke by more than this trips.
    pub stroke_overtravel_m: f32,
    /// |ω_ref − ω| above this for `speed_following_time_s` trips.
    pub speed_following_error_rad_s: f32,
    pub speed_following_time_s: f32,
    /// No encoder count for `encoder_lost_time_s` while |ω_ref| exceeds
    /// `encoder_lost_speed_rad_s`: the signal is lost or the rotor stalled.
    pub encoder_lost_speed_rad_s: f32,
    pub encoder_lost_time_s: f32,
    /// Soft limits: a controlled stop starts when the stopping distance at
    /// `stop_deceleration_m_s2` would carry the motor more than this beyond
    /// the stroke, so it stops inside `stroke ± margin` (and before the
    /// overtravel trip and the end stops).
    pub stroke_soft_margin_m: f32,
    /// Deceleration of a controlled stop.
    pub stop_deceleration_m_s2: f32,
    /// Largest believable error-observer shift; beyond it (or non-finite) the
    /// observer is switched off and the drive stops.
    pub observer_shift_max_m: f32,
    /// Largest |i_a + i_b + i_c| believed (the motor is star-connected, so
    /// the true sum is zero); above it a current sensor is faulty.
    pub current_sum_max_a: f32,
    /// …for this many consecutive PWM periods.
    pub current_sum_periods: u32,
    /// A controlled stop that lets the rod stray this far from its own path
    /// cannot hold the load: escalate to bridge off with the brake applied,
    /// if the brake holds more than the motor can at its present limit.
    pub stop_following_error_m: f32,
    /// Open-phase check: judged over windows of this length…
    pub open_phase_window_s: f32,
    /// …in which the reference asks a phase for at least this mean |i|…
    pub open_phase_current_a: f32,
    /// …and the phase carries less than this share of it.
    pub open_phase_ratio: f32,
}

/// The spring-applied holding brake on the motor shaft (power to open).
/// A vertical leg must not drop its payload when the bridge goes off.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct BrakeParams {
    /// False: no brake; `Disable` switches the bridge off at once.
    pub fitted: bool,
    /// Coil energised to brake open (catalogue release time): a move waits
    /// this long after `Enable`.
    pub release_time_s: f32,
    /// Coil off to brake holding: after `Disable` the loops hold the rod
    /// this long before the bridge goes off.
    pub engage_time_s: f32,
    /// Static holding torque at the motor shaft. A failing controlled stop
    /// hands the load to the brake only when the brake is the stronger of
    /// the two (the motor's current limit may have folded back).
    pub holding_torque_n_m: f32,
    /// `Enable` builds the holding torque (the hold current measured when
    /// the brake last closed, or the expected load) this long with the brake
    /// still closed, so the rod does not sag when it lets go.
    pub preload_time_s: f32,
    /// From enable until the position loop first holds the rod still, the
    /// motor side may leave its command by at most this while the q
    /// current pushes back towards it; beyond it the torque does not make
    /// the motion (a commutation offset error): bridge off, brake closed.
    pub torque_watch_travel_m: f32,
    /// A stop handed to the brake (`Braking` under the motor's assist)
    /// counts a motor-side move of more than this, while the motor's share
    /// ramps down, as the brake slipping: the motor takes its whole share
    /// back. Above the position noise and the disc's elastic twist at its
    /// holding torque, well below the stop's `faults.stop_following_error_m`.
    #[serde(default = "handover_slip_default")]
    pub handover_slip_m: f32,
}

/// Parameter records and files written before the slip was a parameter
/// keep the value it had as a constant.
const fn handover_slip_default() -> f32 {
    5.0e-4
}

/// I²t winding protection: a first-order thermal model normalised to the
/// continuous current, `τ dθ/dt = |i|²/I_c² − θ`; θ = 1 is the steady state
/// at the continuous rating.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct ThermalParams {
    /// Continuous current (peak phase amplitude) the winding tolerates.
    pub continuous_current_a: f32,
    /// Winding thermal time constant.
    pub time_constant_s: f32,
    /// From this θ on, the current limit folds back linearly to the
    /// continuous current, reached at θ = 1.
    pub foldback_start: f32,
    /// θ that latches the fault (reachable only if the continuous current is
    /// exceeded, i.e. the foldback could not hold it).
    pub trip_level: f32,
}

/// What the hardware can take: limits above these are refused at load time.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct RatingParams {
    /// Motor peak current (demagnetisation bound), phase amplitude.
    pub motor_peak_current_a: f32,
    /// Inverter (switches, shunts) peak current.
    pub inverter_peak_current_a: f32,
    /// DC-link capacitor and switch voltage rating.
    pub bus_max_voltage_v: f32,
    /// Mechanical speed rating of motor and screw (critical speed).
    pub speed_max_rad_s: f32,
}

/// Load-force estimate from the q-axis current.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct LoadEstimateParams {
    /// First-order low-pass corner on the estimate.
    pub filter_hz: f32,
}

/// Terminal-error compensation by the observer (see `compensation`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct CompensationParams {
    /// Compensation on at power-up (it can be switched at run time).
    pub enabled_at_start: bool,
    /// Largest shift applied (the paper's largest compensation, 1.5 mm).
    pub shift_max_m: f32,
    /// Largest rate of change of the shift.
    pub shift_rate_max_m_s: f32,
    /// The observer's force input. `false`: the load cell where one is
    /// fitted (the compiled model is trained on it); a drive without one
    /// reads the estimate. `true`: the estimate from the q current, with
    /// the rotating inertia, the viscous drag and the identified Coulomb
    /// friction taken out (`load_estimate`), even with a load cell fitted;
    /// run it with a model trained on that input (docs/observer-retraining.md,
    /// "Without a load cell").
    #[serde(default)]
    pub force_from_estimate: bool,
}

/// A plain PI: parameter records and files written before the weight
/// existed keep their behaviour.
const fn speed_setpoint_weight_default() -> f32 {
    1.0
}

/// The whole parameter set of the control core.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct ControlParams {
    pub motor: MotorParams,
    pub drive_train: DriveTrainParams,
    pub rates: RateParams,
    /// d- and q-axis current PI (V/A, V/(A·s)).
    pub current_pi: PiGains,
    /// Speed PI (A per rad/s, A per rad).
    pub speed_pi: PiGains,
    /// Setpoint weight `b` of the speed PI's proportional term (2-DOF):
    /// `u = kp (b ω_ref − ω) + ki ∫(ω_ref − ω) dt`. Shapes the reference
    /// response (overshoot) without touching the loop's disturbance
    /// response or margins; 1 is the plain PI. In [0, 2].
    #[serde(default = "speed_setpoint_weight_default")]
    pub speed_setpoint_weight: f32,
    /// Corner of the 2nd-order low-pass on the q-current reference
    /// (torque command filter); 0 switches it off.
    pub torque_filter_hz: f32,
    /// Position P gain (1/s): speed command per metre of position error.
    pub position_kp_per_s: f32,
    pub encoder: EncoderParams,
    pub trajectory: TrajectoryParams,
    pub limits: LimitParams,
    pub faults: FaultParams,
    pub load_estimate: LoadEstimateParams,
    pub startup: StartupParams,
    pub calibration: CalibrationParams,
    pub commutation: CommutationParams,
    pub homing: HomingParams,
    pub power_stage: PowerStageParams,
    pub stream: StreamParams,
    pub thermal: ThermalParams,
    pub ratings: RatingParams,
    pub compensation: CompensationParams,
    pub brake: BrakeParams,
}

impl ControlParams {
    /// Total inertia seen at the motor shaft, with the moving mass reflected
    /// through the lead: `J + m (L/2π)²`.
    pub const fn reflected_inertia_kg_m2(&self) -> f32 {
        let r = self.drive_train.screw_lead_m / (2.0 * PI);
        self.drive_train.rotating_inertia_kg_m2 + self.drive_train.moving_mass_kg * r * r
    }

    /// Torque per q-axis ampere, `1.5 p ψ_f` (surface magnets, `L_d = L_q`).
    pub const fn torque_constant_n_m_a(&self) -> f32 {
        1.5 * self.motor.pole_pairs as f32 * self.motor.flux_linkage_wb
    }

    /// The rod force the motor's peak current rating gives, N (forward
    /// efficiency): the largest force a stream may ask to feed forward.
    pub const fn thrust_peak_n(&self) -> f32 {
        self.torque_constant_n_m_a() * self.ratings.motor_peak_current_a * self.drive_train.screw_efficiency / self.metres_per_rad()
    }

    pub fn pwm_period_s(&self) -> f32 {
        1.0 / self.rates.pwm_frequency_hz
    }

    pub fn speed_period_s(&self) -> f32 {
        self.rates.speed_loop_divider as f32 / self.rates.pwm_frequency_hz
    }

    pub fn position_period_s(&self) -> f32 {
        self.rates.position_loop_divider as f32 / self.rates.pwm_frequency_hz
    }

    /// Largest current magnitude both Eq. 19 current bounds allow.
    pub fn current_limit_a(&self) -> f32 {
        let copper = crate::math::sqrt(
            self.limits.copper_power_max_w / (1.5 * self.motor.phase_resistance_ohm),
        );
        if copper < self.limits.current_max_a { copper } else { self.limits.current_max_a }
    }

    /// The same drive with its electrical offset and reference known at
    /// power-up: an absolute encoder, or a drive already started up. The
    /// simulator's experiments (paper run, data sets, fault scenarios)
    /// start from here; the power-up suite does not.
    pub const fn commissioned(self) -> Self {
        let mut p = self;
        p.startup.commutation_known = true;
        p.startup.homed = true;
        p
    }

    /// Metres of nut travel per motor radian, `L_s / 2π`.
    pub const fn metres_per_rad(&self) -> f32 {
        self.drive_train.screw_lead_m / (2.0 * PI)
    }
}

