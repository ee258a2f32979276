//! The power-up suite: the drive started the way a real board starts it —
//! rotor at an unknown angle, encoder zero anywhere, the rated load hanging
//! on the closed brake, amplifier offsets uncorrected — and the ways that
//! start goes wrong (blocked rotor, swapped phases, wrong pole count,
//! unplugged encoder, a supply that sags, a brake that slips, homing that
//! finds nothing). `host-sim power-up --out DIR`; over a rig family,
//! `--family DIR` (`family`).

pub mod cases;
pub mod family;
pub mod report;
pub mod run;

pub use cases::{suite, Failure, PowerUpCase};
pub use report::{summarise, write_report};
pub use run::{homing_repeatability, run_case, CaseResult};
