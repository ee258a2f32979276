//! Parameters of the drive's life around the loops: what it may do at power
//! up, the current-offset calibration, commutation under load, homing, and
//! the power stage's own limits (temperature, regeneration).

use serde::{Deserialize, Serialize};

/// What the drive knows, and may do, when it starts.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct StartupParams {
    /// `encoder.electrical_offset_rad` is valid at power-up: true only for an
    /// absolute encoder mounted and measured once (or a simulated rig that
    /// models one). An incremental encoder loses the offset at every power
    /// cycle, so the firmware's default is false and `Enable` is refused until
    /// the commutation step has run.
    pub commutation_known: bool,
    /// The position counter is referenced to the rod at power-up (an absolute
    /// encoder). False: moves wait for homing; the stroke and soft limits act
    /// only once homed.
    pub homed: bool,
    /// Axial load expected on the rod at power-up, newtons, positive opposing
    /// extension (the payload's weight on a vertical axis). Preloads the
    /// motor before the brake first lets go, while no hold current has been
    /// measured yet. 0 when unknown: the loops then pick the load up as it
    /// sags (≈ 0.1 mm for the rated load).
    pub expected_load_force_n: f32,
    /// Unasked motion: true runs the whole start-up (calibrate, commutate,
    /// home) as soon as the host calls `Controller::power_up`. False (the
    /// default): the drive waits for a command.
    pub run_at_power_up: bool,
}

/// Current-sensor offsets, measured with the bridge off.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct CalibrationParams {
    /// Averaging time. 0.1 s (2000 samples) takes the ESC1's 29 mA code
    /// noise below 1 mA.
    pub duration_s: f32,
    /// Largest believable offset per phase: a bigger one is a broken
    /// amplifier or a current flowing with the bridge off.
    pub offset_max_a: f32,
    /// Largest believable RMS noise per phase around the mean.
    pub noise_max_a: f32,
    /// The bus must stay inside its window for the whole average: a sagging
    /// supply shifts the amplifiers' bias and the bus reading alike.
    pub bus_ripple_max_v: f32,
}

/// Finding the electrical offset with the brake closed and the load on.
///
/// The brake holds the shaft through a compliant disc; a current vector of
/// known angle `φ` twists it by `(T/k_brake) sin(φ − θ_e)`. Sweeping `φ`
/// through an electrical turn forwards and back and fitting the first
/// harmonic of the twist gives `θ_e` at the present rotor angle, whatever
/// constant torque the load already puts on the brake (it only shifts the
/// mean). Then a stationary current vector, preloaded against the expected
/// load, takes over from the brake, turns the rotor by a small known
/// electrical angle and back (direction and pole pairs), and hands over to
/// field-oriented control.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct CommutationParams {
    /// Test current of the sweep. 8 A is 0.84 N·m: with the rated load's
    /// 1.1 N·m the disc carries at most 1.9 N·m of its 2.5.
    pub test_current_a: f32,
    /// Current ramps (in, between the phases, handover).
    pub ramp_s: f32,
    /// One electrical turn of the sweep, each way. 0.5 s is 2 Hz against the
    /// ≈ 160 Hz rotor-on-brake resonance: quasi-static.
    pub sweep_s: f32,
    /// The rotor must be still (below `settle_speed_rad_s`) this long before
    /// the sweep starts and after each check move.
    pub settle_s: f32,
    pub settle_speed_rad_s: f32,
    /// Longest wait for a settle before the step fails (`rotor_not_settled`).
    pub settle_timeout_s: f32,
    /// Twist amplitude below this (counts) means the encoder did not see a
    /// torque the brake's compliance must show: no encoder signal.
    pub min_amplitude_counts: f32,
    /// Twist beyond this (mechanical radians) from the start means the disc
    /// slipped: the brake does not hold.
    pub max_twist_rad: f32,
    /// d-axis (stiffness) part of the stationary hold vector.
    pub hold_current_d_a: f32,
    /// Electrical angle of the check move (0.2 rad, 11.5°: 0.04 mm of rod);
    /// the dither on top swings half of it.
    pub check_angle_rad: f32,
    /// Time for the check move each way (raised cosine).
    pub check_time_s: f32,
    /// Bound for `blocked_ratio` (which must stay below `1 − this`). The
    /// wrong-pole-count threshold itself sits midway between 1 and the
    /// neighbouring counts' ratios `p/(p ± 1)` (`lifecycle::commutation`).
    pub ratio_tolerance: f32,
    /// |measured / expected rotation| below this: the rotor is blocked.
    pub blocked_ratio: f32,
    /// Whole step bound: beyond it the step fails (`lifecycle_timeout`).
    pub timeout_s: f32,
}

/// How the drive finds the rod's reference position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HomingMethod {
    /// Drive into the end stop at a bounded current; the stop defines home.
    HardStop,
    /// Drive until the home switch closes; its edge defines home.
    Switch,
}

/// Homing on an incremental encoder.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct HomingParams {
    #[tree(with = miniconf::leaf)]
    pub method: HomingMethod,
    /// −1: towards the retracted end, +1: towards the extended end.
    pub direction: i32,
    /// Approach speed at the rod. 20 mm/s: the 140 kg payload meets the stop
    /// with 28 mJ, and the contact is judged after it settles.
    pub speed_m_s: f32,
    /// q-current bound while homing: above the rated load's 10.5 A holding
    /// current so the rod can be lifted, low enough that the push into the
    /// stop stays near the rated thrust.
    pub current_max_a: f32,
    /// Hard stop: the rod counts as at the stop when the command has run
    /// ahead of it by this much…
    pub contact_following_m: f32,
    /// …and it has been slower than `contact_speed_rad_s` this long.
    pub contact_speed_rad_s: f32,
    pub contact_time_s: f32,
    /// User position of the contact point (hard stop) or the switch edge.
    pub home_position_m: f32,
    /// After homing the rod moves this far from home, away from the stop.
    pub backoff_m: f32,
    /// Travel without meeting the stop or the switch that fails homing
    /// (`homing_failed`): the stroke plus the distance to the stops.
    pub travel_max_m: f32,
    /// Speed of a `Jog` on a drive not yet homed (the only motion allowed
    /// then: the stroke limits do not yet mean anything).
    pub jog_speed_max_m_s: f32,
}

/// The power stage's own protections.
#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct PowerStageParams {
    /// Heat-sink temperature where the current limit starts to fold back…
    pub temperature_foldback_c: f32,
    /// …reaching zero here, where the drive trips (`power_stage_overtemp`).
    pub temperature_trip_c: f32,
    /// Bus voltage where regeneration starts to be bounded…
    pub regen_bus_start_v: f32,
    /// …and the voltage at which no regenerated power is accepted.
    pub regen_bus_max_v: f32,
    /// Regenerated power the bus may take below `regen_bus_start_v`.
    pub regen_power_max_w: f32,
    /// Encoder plausibility from the back-EMF (`protection::emf_watch`): the
    /// EMF vector turning in the current loop's frame faster than this
    /// (mechanical speed) for `emf_mismatch_time_s` latches `encoder_lost`,
    /// even at standstill (a slipping vertical load).
    pub emf_speed_mismatch_rad_s: f32,
    pub emf_mismatch_time_s: f32,
}
