//! Every rate, gain and limit of the drive, in one place.
//!
//! The firmware compiles `ControlParams::DEFAULT`; the simulator reads the same
//! struct from the `[control]` table of its TOML file (feature `serde`), so a
//! gain tuned in simulation is the gain that ships. Defaults derive from the
//! paper's Table 1 (400 W, 3000 rpm, 250 mm/s, 1.38 kN, 500 mm stroke, 5 mm lead)
//! and a 48 V, 4-pole-pair servo motor of that rating; each value says why.

use core::f32::consts::PI;

#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// Electrical model of the PMSM as the controller believes it (nameplate).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
}

/// Loop rates. The current loop runs every PWM period; the outer loops are
/// decimated from it so all three stay phase-locked to the ADC trigger.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
pub struct PiGains {
    /// Proportional gain (output unit per error unit).
    pub kp: f32,
    /// Integral gain (output unit per error unit per second).
    pub ki: f32,
}

/// Quadrature encoder and its tracking observer (a type-2 PLL).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
pub struct TrajectoryParams {
    pub max_velocity_m_s: f32,
    pub max_acceleration_m_s2: f32,
    pub max_jerk_m_s3: f32,
}

/// The paper's Eq. 19 operating limits plus the inverter's.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
}

/// I²t winding protection: a first-order thermal model normalised to the
/// continuous current, `τ dθ/dt = |i|²/I_c² − θ`; θ = 1 is the steady state
/// at the continuous rating.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
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
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
pub struct LoadEstimateParams {
    /// First-order low-pass corner on the estimate.
    pub filter_hz: f32,
}

/// Rotor alignment: lock the rotor on a d-axis current at electrical angle
/// zero and read the encoder there (incremental encoders lose the offset at
/// every power-up).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
pub struct AlignmentParams {
    pub current_a: f32,
    pub duration_s: f32,
}

/// Terminal-error compensation by the observer (see `compensation`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
pub struct CompensationParams {
    /// Compensation on at power-up (it can be switched at run time).
    pub enabled_at_start: bool,
    /// Largest shift applied (the paper's largest compensation, 1.5 mm).
    pub shift_max_m: f32,
    /// Largest rate of change of the shift.
    pub shift_rate_max_m_s: f32,
}

/// The whole parameter set of the control core.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize), serde(deny_unknown_fields))]
pub struct ControlParams {
    pub motor: MotorParams,
    pub drive_train: DriveTrainParams,
    pub rates: RateParams,
    /// d- and q-axis current PI (V/A, V/(A·s)).
    pub current_pi: PiGains,
    /// Speed PI (A per rad/s, A per rad).
    pub speed_pi: PiGains,
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
    pub alignment: AlignmentParams,
    pub thermal: ThermalParams,
    pub ratings: RatingParams,
    pub compensation: CompensationParams,
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
    pub fn reflected_inertia_kg_m2(&self) -> f32 {
        let r = self.drive_train.screw_lead_m / (2.0 * PI);
        self.drive_train.rotating_inertia_kg_m2 + self.drive_train.moving_mass_kg * r * r
    }

    /// Torque per q-axis ampere, `1.5 p ψ_f` (surface magnets, `L_d = L_q`).
    pub fn torque_constant_n_m_a(&self) -> f32 {
        1.5 * self.motor.pole_pairs as f32 * self.motor.flux_linkage_wb
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

    /// Metres of nut travel per motor radian, `L_s / 2π`.
    pub fn metres_per_rad(&self) -> f32 {
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
        },
        load_estimate: LoadEstimateParams { filter_hz: 5.0 },
        // Rated current: enough torque to pull the rotor against the screw's
        // friction, short enough not to heat it.
        alignment: AlignmentParams { current_a: 12.0, duration_s: 0.5 },
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
        p
    };
}

impl Default for ControlParams {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// A parameter that cannot be used, named by its path in the TOML file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamError {
    pub field: &'static str,
    pub reason: &'static str,
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "parameter `{}`: {}", self.field, self.reason)
    }
}

// Out of line: validation runs once at start-up, and ≈ 60 inlined copies
// of these checks cost ≈ 1.6 KB of the 32 KB flash (measured).
#[inline(never)]
fn positive(field: &'static str, v: f32) -> Result<(), ParamError> {
    if !v.is_finite() {
        Err(ParamError { field, reason: "must be finite" })
    } else if v <= 0.0 {
        Err(ParamError { field, reason: "must be > 0" })
    } else {
        Ok(())
    }
}

#[inline(never)]
fn non_negative(field: &'static str, v: f32) -> Result<(), ParamError> {
    if !v.is_finite() {
        Err(ParamError { field, reason: "must be finite" })
    } else if v < 0.0 {
        Err(ParamError { field, reason: "must be >= 0" })
    } else {
        Ok(())
    }
}

#[inline(never)]
fn nonzero(field: &'static str, v: u32) -> Result<(), ParamError> {
    if v == 0 { Err(ParamError { field, reason: "must be >= 1" }) } else { Ok(()) }
}

impl ControlParams {
    /// Refuses a parameter set the loops cannot run with, naming the field.
    pub fn validate(&self) -> Result<(), ParamError> {
        let m = &self.motor;
        nonzero("control.motor.pole_pairs", m.pole_pairs)?;
        positive("control.motor.phase_resistance_ohm", m.phase_resistance_ohm)?;
        positive("control.motor.inductance_d_h", m.inductance_d_h)?;
        positive("control.motor.inductance_q_h", m.inductance_q_h)?;
        positive("control.motor.flux_linkage_wb", m.flux_linkage_wb)?;
        let d = &self.drive_train;
        positive("control.drive_train.screw_lead_m", d.screw_lead_m)?;
        positive("control.drive_train.screw_efficiency", d.screw_efficiency)?;
        if d.screw_efficiency > 1.0 {
            return Err(ParamError { field: "control.drive_train.screw_efficiency", reason: "must be <= 1" });
        }
        positive("control.drive_train.rotating_inertia_kg_m2", d.rotating_inertia_kg_m2)?;
        non_negative("control.drive_train.moving_mass_kg", d.moving_mass_kg)?;
        non_negative("control.drive_train.viscous_friction_n_m_s_rad", d.viscous_friction_n_m_s_rad)?;
        positive("control.rates.pwm_frequency_hz", self.rates.pwm_frequency_hz)?;
        nonzero("control.rates.speed_loop_divider", self.rates.speed_loop_divider)?;
        nonzero("control.rates.position_loop_divider", self.rates.position_loop_divider)?;
        if !self.rates.position_loop_divider.is_multiple_of(self.rates.speed_loop_divider) {
            return Err(ParamError {
                field: "control.rates.position_loop_divider",
                reason: "must be a multiple of speed_loop_divider",
            });
        }
        positive("control.current_pi.kp", self.current_pi.kp)?;
        non_negative("control.current_pi.ki", self.current_pi.ki)?;
        positive("control.speed_pi.kp", self.speed_pi.kp)?;
        non_negative("control.speed_pi.ki", self.speed_pi.ki)?;
        non_negative("control.torque_filter_hz", self.torque_filter_hz)?;
        positive("control.position_kp_per_s", self.position_kp_per_s)?;
        let e = &self.encoder;
        nonzero("control.encoder.counts_per_rev", e.counts_per_rev)?;
        if e.counts_per_rev > 32_768 {
            // The core unwraps a 16-bit counter: one revolution must fit in half its range.
            return Err(ParamError { field: "control.encoder.counts_per_rev", reason: "must be <= 32768" });
        }
        if e.direction != 1 && e.direction != -1 {
            return Err(ParamError { field: "control.encoder.direction", reason: "must be 1 or -1" });
        }
        if !e.electrical_offset_rad.is_finite() {
            return Err(ParamError { field: "control.encoder.electrical_offset_rad", reason: "must be finite" });
        }
        positive("control.encoder.pll_kp_per_s", e.pll_kp_per_s)?;
        positive("control.encoder.pll_ki_per_s2", e.pll_ki_per_s2)?;
        let t = &self.trajectory;
        positive("control.trajectory.max_velocity_m_s", t.max_velocity_m_s)?;
        positive("control.trajectory.max_acceleration_m_s2", t.max_acceleration_m_s2)?;
        positive("control.trajectory.max_jerk_m_s3", t.max_jerk_m_s3)?;
        let l = &self.limits;
        positive("control.limits.current_max_a", l.current_max_a)?;
        positive("control.limits.copper_power_max_w", l.copper_power_max_w)?;
        positive("control.limits.speed_max_rad_s", l.speed_max_rad_s)?;
        non_negative("control.limits.stroke_min_m", l.stroke_min_m)?;
        positive("control.limits.stroke_max_m", l.stroke_max_m)?;
        if l.stroke_max_m <= l.stroke_min_m {
            return Err(ParamError { field: "control.limits.stroke_max_m", reason: "must exceed stroke_min_m" });
        }
        positive("control.limits.max_modulation", l.max_modulation)?;
        if l.max_modulation > 1.0 {
            return Err(ParamError { field: "control.limits.max_modulation", reason: "must be <= 1" });
        }
        let f = &self.faults;
        positive("control.faults.overcurrent_trip_a", f.overcurrent_trip_a)?;
        if f.overcurrent_trip_a < l.current_max_a {
            return Err(ParamError {
                field: "control.faults.overcurrent_trip_a",
                reason: "must be >= limits.current_max_a, or normal operation trips",
            });
        }
        positive("control.faults.bus_overvoltage_v", f.bus_overvoltage_v)?;
        positive("control.faults.bus_undervoltage_v", f.bus_undervoltage_v)?;
        if f.bus_overvoltage_v <= f.bus_undervoltage_v {
            return Err(ParamError { field: "control.faults.bus_overvoltage_v", reason: "must exceed bus_undervoltage_v" });
        }
        nonzero("control.faults.encoder_max_step_counts", f.encoder_max_step_counts)?;
        positive("control.faults.encoder_max_innovation_counts", f.encoder_max_innovation_counts)?;
        positive("control.faults.position_following_error_m", f.position_following_error_m)?;
        non_negative("control.faults.stroke_overtravel_m", f.stroke_overtravel_m)?;
        positive("control.load_estimate.filter_hz", self.load_estimate.filter_hz)?;
        positive("control.alignment.current_a", self.alignment.current_a)?;
        if self.alignment.current_a > l.current_max_a {
            return Err(ParamError { field: "control.alignment.current_a", reason: "must be <= limits.current_max_a" });
        }
        positive("control.alignment.duration_s", self.alignment.duration_s)?;
        positive("control.faults.speed_following_error_rad_s", f.speed_following_error_rad_s)?;
        positive("control.faults.speed_following_time_s", f.speed_following_time_s)?;
        positive("control.faults.encoder_lost_speed_rad_s", f.encoder_lost_speed_rad_s)?;
        positive("control.faults.encoder_lost_time_s", f.encoder_lost_time_s)?;
        non_negative("control.faults.stroke_soft_margin_m", f.stroke_soft_margin_m)?;
        if f.stroke_soft_margin_m >= f.stroke_overtravel_m {
            return Err(ParamError {
                field: "control.faults.stroke_soft_margin_m",
                reason: "must be below stroke_overtravel_m, or a controlled stop ends in a trip",
            });
        }
        positive("control.faults.stop_deceleration_m_s2", f.stop_deceleration_m_s2)?;
        if f.stop_deceleration_m_s2 < self.trajectory.max_acceleration_m_s2 {
            return Err(ParamError {
                field: "control.faults.stop_deceleration_m_s2",
                reason: "must be >= trajectory.max_acceleration_m_s2, or planned moves trip the soft limits",
            });
        }
        positive("control.faults.observer_shift_max_m", f.observer_shift_max_m)?;
        positive("control.faults.current_sum_max_a", f.current_sum_max_a)?;
        nonzero("control.faults.current_sum_periods", f.current_sum_periods)?;
        let c = &self.compensation;
        positive("control.compensation.shift_max_m", c.shift_max_m)?;
        if c.shift_max_m > f.observer_shift_max_m {
            return Err(ParamError {
                field: "control.compensation.shift_max_m",
                reason: "must be <= faults.observer_shift_max_m",
            });
        }
        positive("control.compensation.shift_rate_max_m_s", c.shift_rate_max_m_s)?;
        let th = &self.thermal;
        positive("control.thermal.continuous_current_a", th.continuous_current_a)?;
        if th.continuous_current_a > l.current_max_a {
            return Err(ParamError { field: "control.thermal.continuous_current_a", reason: "must be <= limits.current_max_a" });
        }
        positive("control.thermal.time_constant_s", th.time_constant_s)?;
        positive("control.thermal.foldback_start", th.foldback_start)?;
        if th.foldback_start >= 1.0 {
            return Err(ParamError { field: "control.thermal.foldback_start", reason: "must be < 1" });
        }
        if !(th.trip_level > 1.0) || !th.trip_level.is_finite() {
            return Err(ParamError { field: "control.thermal.trip_level", reason: "must be finite and > 1" });
        }
        let r = &self.ratings;
        positive("control.ratings.motor_peak_current_a", r.motor_peak_current_a)?;
        positive("control.ratings.inverter_peak_current_a", r.inverter_peak_current_a)?;
        positive("control.ratings.bus_max_voltage_v", r.bus_max_voltage_v)?;
        positive("control.ratings.speed_max_rad_s", r.speed_max_rad_s)?;
        if l.current_max_a > r.motor_peak_current_a || l.current_max_a > r.inverter_peak_current_a {
            return Err(ParamError {
                field: "control.limits.current_max_a",
                reason: "above the motor or inverter peak rating (control.ratings)",
            });
        }
        if f.overcurrent_trip_a > r.inverter_peak_current_a {
            return Err(ParamError {
                field: "control.faults.overcurrent_trip_a",
                reason: "above control.ratings.inverter_peak_current_a",
            });
        }
        if f.bus_overvoltage_v > r.bus_max_voltage_v {
            return Err(ParamError { field: "control.faults.bus_overvoltage_v", reason: "above control.ratings.bus_max_voltage_v" });
        }
        if l.speed_max_rad_s > r.speed_max_rad_s {
            return Err(ParamError { field: "control.limits.speed_max_rad_s", reason: "above control.ratings.speed_max_rad_s" });
        }
        Ok(())
    }
}
