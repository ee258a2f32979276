//! The telemetry record: one struct, logged by the firmware through defmt and
//! written by the simulator as a CSV row, so both carry the same named fields.

use crate::lifecycle::Readiness;
use crate::protection::{FaultSet, LimitFlags};

/// What the drive is doing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub enum Mode {
    /// Bridge off, loops reset, encoder still tracked.
    #[default]
    Disabled,
    /// Current-offset calibration, bridge off.
    Calibrating,
    /// Commutation: the electrical offset found with the brake holding the
    /// load, then direction and pole pairs checked (`lifecycle::commutation`).
    Aligning,
    /// Homing: closed loop towards the end stop or switch, bounded current.
    Homing,
    /// Position control.
    Running,
    /// A controlled-stop fault latched: decelerating, then holding, bridge on.
    Stopping,
    /// A fault latched; bridge off until cleared.
    Fault,
    /// `Disable` with a brake fitted: stopping on the stop ramp, then holding
    /// while the brake closes; the bridge goes off after
    /// `brake.engage_time_s` so the load never hangs on nothing.
    Braking,
    /// `Enable` with a brake fitted: the loops hold and the hold current
    /// builds for `brake.preload_time_s` with the brake still closed; then
    /// `Running` (the brake told to open).
    Preloading,
}

/// A snapshot of the drive, refreshed every position-loop period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub struct Telemetry {
    /// Time since the controller was created, from its own period count.
    pub time_s: f32,
    pub mode: Mode,
    /// Trajectory position (before any setpoint shift).
    pub position_reference_m: f32,
    /// What the position loop was asked to reach (reference + shift, clamped).
    pub position_command_m: f32,
    /// The compensation shift in that command (observer + external).
    pub position_shift_m: f32,
    /// Motor-side position, `L θ_m / 2π`.
    pub motor_position_m: f32,
    /// Multi-turn mechanical motor angle.
    pub motor_angle_rad: f32,
    pub speed_reference_rad_s: f32,
    pub speed_rad_s: f32,
    pub current_d_a: f32,
    pub current_q_a: f32,
    pub current_q_reference_a: f32,
    pub voltage_d_v: f32,
    pub voltage_q_v: f32,
    pub bus_voltage_v: f32,
    /// Linear-scale (piston-rod) position, if a scale is fitted.
    pub terminal_position_m: Option<f32>,
    /// The observer's force input: the load cell when fitted, or the
    /// estimate from i_q when none is or `compensation.force_from_estimate`
    /// selects it; low-passed at `load_estimate.filter_hz`.
    pub load_force_estimate_n: f32,
    pub faults: FaultSet,
    pub limits: LimitFlags,
    /// Start-up steps done (calibrated, commutated, homed).
    pub readiness: Readiness,
}
