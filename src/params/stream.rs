//! Streamed setpoints (`Command::Stream`).

use serde::{Deserialize, Serialize};

/// Drives on one platform's setpoint bus: the legs of the Stewart platform,
/// each reading its own slot of the setpoint frame.
pub const LEGS: usize = 6;

#[derive(Clone, Copy, Debug, PartialEq)]
#[derive(Serialize, Deserialize, postcard_schema::Schema, miniconf::Tree)]
#[serde(deny_unknown_fields)]
pub struct StreamParams {
    /// The slowest setpoint rate the drive interpolates over (100 Hz): the
    /// first setpoint is reached over this, and a measured interval never
    /// exceeds it.
    pub period_max_s: f32,
    /// The longest gap after which a setpoint still joins the stream: a
    /// later one is refused. The stream itself is lost sooner, one expected
    /// interval after its newest setpoint was reached (where the reference
    /// began to decelerate); the deceleration goes on to rest and latches
    /// `stream_timeout`.
    pub timeout_s: f32,
    /// This drive's slot (leg 0…5) in the platform's CAN FD setpoint frame
    /// (`protocol::can`): each of the six drives on the bus reads its own.
    pub leg_index: u32,
    /// Switch this drive's CAN bus terminator in (the board's 120 Ω across
    /// CANH–CANL): true on the two drives at the physical ends of the bus,
    /// false on the others (ISO 11898-2: 120 Ω at each end, 60 Ω measured
    /// between CANH and CANL with the bus unpowered). A board that cannot
    /// switch a terminator refuses `true` (at build time for the image's
    /// set, at load for a saved one), naming this field. Absent from a
    /// TOML file: false.
    #[serde(default)]
    pub can_termination: bool,
    /// How far the points' velocity may disagree with their position
    /// steps, m/s, averaged over `timeout_s` on the drive's clock (so one
    /// point bunched with its neighbour or late by an interval moves the
    /// average by at most `v·interval/timeout_s`). A velocity column in
    /// other units, or points recorded at 100 Hz arriving at 1 kHz (ten
    /// times too fast), disagree by far more; the point is refused and
    /// named. At most half the top stream speed. Absent from a TOML file:
    /// 0.05 m/s.
    #[serde(default = "velocity_mismatch_max_default")]
    pub velocity_mismatch_max_m_s: f32,
}

/// A quarter of the top stream speed (0.2 m/s): one point late by a whole
/// 10 ms interval at 0.2 m/s moves the 50 ms average by 0.04 m/s.
pub const VELOCITY_MISMATCH_MAX_DEFAULT_M_S: f32 = 0.05;

fn velocity_mismatch_max_default() -> f32 {
    VELOCITY_MISMATCH_MAX_DEFAULT_M_S
}
