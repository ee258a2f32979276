//! Faults that stop the drive and limits that bound it.

pub mod faults;
pub mod limits;
pub mod thermal;

pub use faults::FaultSet;
pub use limits::{clamp_to_stroke, LimitFlags};
pub use thermal::ThermalModel;
