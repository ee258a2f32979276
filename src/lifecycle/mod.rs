//! The drive's start-up steps, before the loops may run: current-offset
//! calibration, commutation under load, homing. Each is a small state
//! machine fed once per period by `Controller`; each ends in a result or a
//! named fault, never in a guess.
//!
//! off → calibrating (bridge off) → aligning (commutation, brake closed, then
//! a stationary current vector) → homing (closed loop, bounded current) →
//! ready (bridge on, holding) → running.

pub mod calibration;
pub mod commutation;
pub mod homing;

pub use calibration::{CurrentCalibration, CalibrationResult};
pub use commutation::{Commutation, CommutationInput, CommutationOutput, CommutationReport, CommutationResult};
pub use homing::{Homing, HomingInput, HomingOutput, SettleVerdict};

/// Which start-up steps are done. Read in telemetry; `Enable` needs
/// `COMMUTATED`, moves and streams need `HOMED` too.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub struct Readiness(u8);

bitflags::bitflags! {
    impl Readiness: u8 {
        const CURRENTS_CALIBRATED = 1 << 0;
        const COMMUTATED = 1 << 1;
        const HOMED = 1 << 2;
    }
}

impl Readiness {
    pub const NONE: Self = Self::empty();
    /// Every start-up step done: the drive may run.
    pub const ALL: Self = Self::all();
}

#[cfg(feature = "defmt")]
impl defmt::Format for Readiness {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(
            f,
            "cal={=bool} comm={=bool} homed={=bool}",
            self.contains(Self::CURRENTS_CALIBRATED),
            self.contains(Self::COMMUTATED),
            self.contains(Self::HOMED)
        );
    }
}
