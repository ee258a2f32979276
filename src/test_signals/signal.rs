//! The test signals a user can ask for.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Schema)]
pub enum TestSignal {
    /// A d- or q-axis current step held for `duration_s`, speed and position
    /// loops suspended (bridge on, brake closed or load blocked by the user).
    CurrentStep { axis_q: bool, amplitude_a: f32, duration_s: f32 },
    /// A speed-reference step about the present speed, position loop suspended.
    SpeedStep { amplitude_rad_s: f32, duration_s: f32 },
    /// A position-reference step (no trajectory), the cascade closed.
    PositionStep { distance_m: f32, duration_s: f32 },
    /// A logarithmic sine sweep added to the reference of `target`.
    Chirp { target: ChirpTarget, amplitude: f32, start_hz: f32, end_hz: f32, duration_s: f32 },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
pub enum ChirpTarget {
    /// q-current reference, amps.
    Current,
    /// Speed reference, rad/s.
    Speed,
    /// Position reference, metres.
    Position,
}

