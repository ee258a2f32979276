//! Host simulator of the direct-driven servo electric cylinder.
//!
//! The plant (`plant`) stands in for the inverter, motor and mechanics; the
//! control core from the firmware crate (`servo_core`) runs unchanged against
//! it (`sim`). `scenario` says what the loop is asked to do, `report` what it
//! leaves behind, `config` reads the rig file, `trainer` fits the error observer.

pub mod config;
pub mod diagnose;
pub mod drive;
pub mod fault_injection;
pub mod plant;
pub mod platform;
pub mod power_up;
pub mod report;
pub mod rigs;
pub mod scenario;
pub mod sim;
pub mod tool;
pub mod trainer;
pub mod tuning;
