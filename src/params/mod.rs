//! Every rate, gain and limit of the drive, in one place.
//!
//! The firmware compiles `ControlParams::DEFAULT`; the simulator reads the same
//! struct from the `[control]` table of its TOML file (feature `serde`), so a
//! gain tuned in simulation is the gain that ships. Defaults derive from the
//! paper's Table 1 (400 W, 3000 rpm, 250 mm/s, 1.38 kN, 500 mm stroke, 5 mm lead)
//! and a 48 V, 4-pole-pair servo motor of that rating; each value says why.

use core::f32::consts::PI;

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

const CURRENT_BANDWIDTH_RAD_S: f32 = 2.0 * PI * 1000.0;
const MOTOR_R_OHM: f32 = 0.12;
const MOTOR_L_H: f32 = 0.35e-3;
const MOTOR_PSI_WB: f32 = 0.0175;
const POLE_PAIRS: u32 = 4;
/// Rotor 0.30e-4 + coupling 0.02e-4 + Ø20×600 mm steel screw 0.74e-4 kg·m².
const ROTATING_INERTIA: f32 = 1.06e-4;
/// Rated thrust 1.38 kN borne vertically: 1380 / 9.81 ≈ 140.7 kg nut+rod+payload.
const MOVING_MASS_KG: f32 = 140.7;
const LEAD_M: f32 = 0.005;
const SPEED_BANDWIDTH_RAD_S: f32 = 2.0 * PI * 40.0;
const ENCODER_PLL_RAD_S: f32 = 2.0 * PI * 400.0;

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

    pub const DEFAULT: Self = Self {
        motor: MotorParams {
            pole_pairs: POLE_PAIRS,
            phase_resistance_ohm: MOTOR_R_OHM,
            inductance_d_h: MOTOR_L_H,
            inductance_q_h: MOTOR_L_H,
            // 1.5·4·0.0175 = 0.105 N·m/A: rated 1.27 N·m at ≈12 A; back-EMF at
            // 3000 rpm is 22 V peak, inside 48 V/√3 = 27.7 V.
            flux_linkage_wb: MOTOR_PSI_WB,
        },
        drive_train: DriveTrainParams {
            screw_lead_m: LEAD_M,
            // DESIGN.md check: 1.38 kN × 5 mm / (2π·0.9) ≈ 1.22 N·m.
            screw_efficiency: 0.9,
            rotating_inertia_kg_m2: ROTATING_INERTIA,
            moving_mass_kg: MOVING_MASS_KG,
            viscous_friction_n_m_s_rad: 2.0e-4,
            // Nut preload drag 0.03 N·m + rod seal 30 N × L/2π (0.024 N·m).
            coulomb_friction_n_m: 0.054,
            // 1 rad/s is 0.8 mm/s of rod: the S-curve passes it in ≈8 ms, so
            // the friction step is taken as a ramp, not a kick to the rod mode.
            friction_feedforward_speed_rad_s: 1.0,
            friction_feedforward_gain: 1.0,
        },
        rates: RateParams { pwm_frequency_hz: 20_000.0, speed_loop_divider: 4, position_loop_divider: 20 },
        // Pole-zero cancellation: kp = L·ω_c, ki = R·ω_c with ω_c = 2π·1 kHz,
        // a twentieth of the PWM rate so the one-period delay costs < 20° phase.
        current_pi: PiGains {
            kp: MOTOR_L_H * CURRENT_BANDWIDTH_RAD_S,
            ki: MOTOR_R_OHM * CURRENT_BANDWIDTH_RAD_S,
        },
        // kp = J_total ω_s / K_t with ω_s = 2π·40 Hz (J_total = 1.95e-4 kg·m²,
        // K_t = 0.105 N·m/A); ki = kp·ω_s/4 puts the PI zero a quarter-decade
        // below crossover. 40 Hz stays clear of the ≈28 Hz rod resonance's
        // anti-resonance region while rejecting the gravity load quickly.
        speed_pi: PiGains {
            kp: 1.95e-4 * SPEED_BANDWIDTH_RAD_S / 0.105,
            ki: 1.95e-4 * SPEED_BANDWIDTH_RAD_S / 0.105 * SPEED_BANDWIDTH_RAD_S / 4.0,
        },
        speed_setpoint_weight: 1.0,
        // The coupling + screw-twist torsional mode sits near 370 Hz at full
        // extension (lower stiffness) with ≈2 % damping; 150 Hz takes its
        // loop gain under one and costs ≈22° at the 40 Hz crossover.
        torque_filter_hz: 150.0,
        // A quarter of the speed bandwidth (ω_s/4 ≈ 63/s): no overshoot; the
        // velocity feedforward carries the tracking.
        position_kp_per_s: SPEED_BANDWIDTH_RAD_S / 4.0,
        encoder: EncoderParams {
            counts_per_rev: 10_000,
            direction: 1,
            electrical_offset_rad: 0.0,
            pll_kp_per_s: 2.0 * ENCODER_PLL_RAD_S,
            pll_ki_per_s2: ENCODER_PLL_RAD_S * ENCODER_PLL_RAD_S,
        },
        // 80 % of Table 1's rated 250 mm/s: at exactly rated speed the
        // position loop has no speed left to correct with (the 3000 rpm limit
        // binds) and the back-EMF leaves no voltage for the current loop.
        // 2.5 m/s² with a 0.1 s jerk time.
        trajectory: TrajectoryParams {
            max_velocity_m_s: 0.2,
            max_acceleration_m_s2: 2.5,
            max_jerk_m_s3: 25.0,
        },
        limits: LimitParams {
            // Three times rated current, the usual servo peak rating.
            current_max_a: 36.0,
            // 1.5·0.12·33.3² = 200 W: twice the rated-torque copper loss plus
            // margin; above it the winding heats faster than the I²t model allows.
            copper_power_max_w: 200.0,
            // 3000 rpm.
            speed_max_rad_s: 2.0 * PI * 3000.0 / 60.0,
            stroke_min_m: 0.0,
            stroke_max_m: 0.5,
            max_modulation: 0.95,
        },
        faults: FaultParams {
            overcurrent_trip_a: 45.0,
            bus_overvoltage_v: 60.0,
            bus_undervoltage_v: 36.0,
            // 3000 rpm = 500 counts per 50 µs at 10 000 counts/rev; 4× margin.
            encoder_max_step_counts: 2_000,
            // 100 counts (3.6° mechanical, 14° electrical): the observer lags
            // the rotor's peak acceleration (36 A on the rotor alone) by ≈30.
            encoder_max_innovation_counts: 100.0,
            position_following_error_m: 0.005,
            stroke_overtravel_m: 0.005,
            // A quarter of rated speed for 50 ms: far outside what the loop
            // leaves in normal running (a few rad/s), quick enough that the
            // rod moves < 5 mm before the stop.
            speed_following_error_rad_s: 80.0,
            speed_following_time_s: 0.05,
            // 30 rad/s gives 48 counts per ms at 10 000 counts/rev; none in
            // 20 ms is no quantisation effect.
            encoder_lost_speed_rad_s: 30.0,
            encoder_lost_time_s: 0.02,
            // Stops land within 2 mm of the stroke ends, inside the 5 mm
            // overtravel trip and the end stops 10 mm out.
            stroke_soft_margin_m: 0.002,
            // Twice the trajectory's: a stop is shorter than any planned move.
            stop_deceleration_m_s2: 5.0,
            // The paper's largest compensation, 1.5 mm, with a third more room.
            observer_shift_max_m: 0.002,
            // ≈100 ADC codes of the ESC1's 29 mA/code: far above noise and
            // quantisation, far below a stuck sensor at rated current (12 A).
            current_sum_max_a: 3.0,
            // 0.5 ms: noise on three channels (σ_Σ = 1.7 A for 1 A each) stays
            // above 3 A ten periods running with odds of 1e-11.
            current_sum_periods: 10,
            // 3 mm: the stop starts from the measured position, so anything
            // near the 5 mm following trip means the load is winning.
            stop_following_error_m: 0.003,
            // 2 ms is a tenth of an electrical turn at rated speed and two
            // windows fit in the 5 ms the open-phase scenario allows; 3 A
            // mean is a quarter of rated current, far above sensor noise;
            // an open lead carries noise only (< 5 %), a healthy phase 100 %.
            open_phase_window_s: 0.002,
            open_phase_current_a: 3.0,
            open_phase_ratio: 0.2,
        },
        load_estimate: LoadEstimateParams { filter_hz: 5.0 },
        // Nothing is known at power-up on an incremental encoder, and nothing
        // moves until asked. The expected load is the rated thrust borne
        // vertically (the payload behind `MOVING_MASS_KG`).
        startup: StartupParams {
            commutation_known: false,
            homed: false,
            expected_load_force_n: 1380.0,
            run_at_power_up: false,
        },
        // 2 A is ≈ 70 ESC1 codes, a tenth of the amplifier's range; 1 A RMS
        // is 35 codes of noise, ten times what a healthy channel shows.
        calibration: CalibrationParams { duration_s: 0.1, offset_max_a: 2.0, noise_max_a: 1.0, bus_ripple_max_v: 2.0 },
        // Reasons in `CommutationParams`. 0.03 rad of twist is 2.4× what
        // the 2.5 N·m disc gives elastically (≈ 200 N·m/rad catalogue class):
        // beyond it the disc slipped.
        commutation: CommutationParams {
            test_current_a: 8.0,
            ramp_s: 0.05,
            sweep_s: 0.5,
            settle_s: 0.05,
            settle_speed_rad_s: 0.5,
            settle_timeout_s: 1.0,
            min_amplitude_counts: 1.5,
            max_twist_rad: 0.03,
            hold_current_d_a: 25.0,
            check_angle_rad: 0.2,
            check_time_s: 0.3,
            ratio_tolerance: 0.15,
            blocked_ratio: 0.3,
            timeout_s: 5.0,
        },
        // Into the lower end stop (10 mm below stroke 0, `plant.stroke`),
        // contact at home_position −0.010 m, then back to stroke 0 + 2 mm.
        homing: HomingParams {
            method: HomingMethod::HardStop,
            direction: -1,
            speed_m_s: 0.02,
            current_max_a: 15.0,
            contact_following_m: 0.0005,
            contact_speed_rad_s: 0.5,
            contact_time_s: 0.3,
            home_position_m: -0.010,
            backoff_m: 0.012,
            travel_max_m: 0.53,
            jog_speed_max_m_s: 0.01,
        },
        // A 48 V stage: fold back from 80 °C, trip at 100 °C (MOSFET
        // junctions ≈ 25 K above the sink at rated current). Regeneration:
        // the bus capacitors take what 54 → 58 V allows, below the 60 V trip;
        // 50 W is what a bench supply with its own small sink may absorb.
        // Back-EMF check: 20 rad/s is 80 rad/s electrical, 1.4 V of EMF, far
        // above the dead-time voltage error at standstill current; netted
        // over 20 ms, the dead time's wobble and a platform leg's reversals
        // cancel (10 ms tripped a streamed platform leg falsely).
        stream: StreamParams { period_max_s: 0.01, timeout_s: 0.05, leg_index: 0, can_termination: false },
        power_stage: PowerStageParams {
            temperature_foldback_c: 80.0,
            temperature_trip_c: 100.0,
            regen_bus_start_v: 54.0,
            regen_bus_max_v: 58.0,
            regen_power_max_w: 50.0,
            emf_speed_mismatch_rad_s: 20.0,
            emf_mismatch_time_s: 0.02,
        },
        // Rated torque 1.27 N·m at K_t = 0.105 → 12 A continuous. A 400 W
        // servo winding's thermal time constant is minutes; 30 s is on the
        // safe side and still allows 3× current for ≈3.5 s from cold.
        thermal: ThermalParams { continuous_current_a: 12.0, time_constant_s: 30.0, foldback_start: 0.8, trip_level: 1.05 },
        // Motor: 3× rated peak (catalogue class); inverter: a 48 V stage
        // rated 50 A peak (the overcurrent trip at 45 A must sit below it); bus: 63 V capacitors; speed: motor 3000 rpm rating (the
        // Ø20×5 screw's critical speed at 600 mm is higher).
        ratings: RatingParams {
            motor_peak_current_a: 36.0,
            inverter_peak_current_a: 50.0,
            bus_max_voltage_v: 63.0,
            speed_max_rad_s: 2.0 * PI * 3000.0 / 60.0,
        },
        // Off at power-up: the operator switches it on once the model in the
        // log is the one trained for this rig. 20 mm/s: the full 0.3 mm sag is
        // taken up in 15 ms, faster than the load changes, and a jump in the
        // load estimate moves the rod at most 20 µm per millisecond.
        compensation: CompensationParams { enabled_at_start: false, shift_max_m: 0.0015, shift_rate_max_m_s: 0.02 },
        // Catalogue class for a 2.5 N·m spring-applied servo brake (≈2× the
        // 1.1 N·m that holds rated thrust): 50 ms to open, 30 ms to close.
        // Preload: 20 ms is eight speed-loop time constants at 40 Hz.
        brake: BrakeParams { fitted: true, release_time_s: 0.05, engage_time_s: 0.03, holding_torque_n_m: 2.5, preload_time_s: 0.02 },
    };
}

impl ControlParams {
    /// The same drive on a 24 V bench supply (B-G431B-ESC1: 28 V max). The
    /// motor's back-EMF reaches the 24 V linear range at about 1700 rpm, so
    /// the speed limit drops to 1500 rpm and the trajectory to 100 mm/s
    /// (1200 rpm); the bus trips move to the supply's window. Everything else
    /// — gains, current limits, stroke — is the default.
    pub const BENCH_24V: Self = {
        let mut p = Self::DEFAULT;
        p.faults.bus_overvoltage_v = 28.0;
        p.faults.bus_undervoltage_v = 18.0;
        p.limits.speed_max_rad_s = 2.0 * PI * 1500.0 / 60.0;
        p.trajectory.max_velocity_m_s = 0.1;
        // Regeneration bounded between 25 and 27 V, under the 28 V trip.
        p.power_stage.regen_bus_start_v = 25.0;
        p.power_stage.regen_bus_max_v = 27.0;
        p
    };
}

impl Default for ControlParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}
