//! Faults that stop the drive and limits that bound it.

pub mod emf_watch;
pub mod faults;
pub mod limits;
pub mod open_phase;
pub mod thermal;
pub mod torque_watch;

pub use emf_watch::EmfWatch;
pub use faults::FaultSet;
pub use limits::{clamp_to_stroke, LimitFlags};
pub use open_phase::OpenPhaseMonitor;
pub use thermal::ThermalModel;
pub use torque_watch::{TorqueLook, TorqueWatch, TorqueWatchVerdict};
