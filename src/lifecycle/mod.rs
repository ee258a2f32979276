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
pub use homing::{Homing, HomingInput, HomingOutput};

/// Which start-up steps are done. Read in telemetry; `Enable` needs
/// `COMMUTATED`, moves and streams need `HOMED` too.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
pub struct Readiness(pub u8);

impl Readiness {
    pub const NONE: Self = Self(0);
    pub const CURRENTS_CALIBRATED: Self = Self(1 << 0);
    pub const COMMUTATED: Self = Self(1 << 1);
    pub const HOMED: Self = Self(1 << 2);
    pub const ALL: Self = Self(0b111);

    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }

    pub fn remove(&mut self, other: Self) {
        self.0 &= !other.0;
    }
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
