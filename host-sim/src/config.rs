//! The rig description: one TOML file with the controller's parameters
//! (`[control]`, the very struct the firmware compiles) and the plant's
//! (`[plant]`). Validated on load; errors name the file and the field.

use crate::plant::{ParamError, PlantParams};
use anyhow::{anyhow, Context, Result};
use serde::Deserialize;
use servo_core::ControlParams;
use std::path::{Path, PathBuf};

/// The rig file shipped with the simulator: nominal plant and default gains.
pub const DEFAULT_RIG_TOML: &str = include_str!("../params/rig.toml");

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RigConfig {
    pub control: ControlParams,
    pub plant: PlantParams,
}

impl RigConfig {
    /// Parses and validates TOML text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self> {
        // serde_path_to_error names the dotted field (`control.motor: missing
        // field …`) rather than only a line number.
        let de = toml::Deserializer::parse(text).map_err(|e| anyhow!("{origin}: {e}"))?;
        let cfg: RigConfig = serde_path_to_error::deserialize(de).map_err(|e| anyhow!("{origin}: `{}`: {}", e.path(), e.inner()))?;
        cfg.validate().map_err(|e| anyhow!("{origin}: {e}"))?;
        Ok(cfg)
    }

    /// Each table on its own, then the bounds that need both: the payload
    /// the plant carries against what its motor and brake can hold.
    pub fn validate(&self) -> std::result::Result<(), ParamError> {
        self.control.validate().map_err(|e| ParamError { field: "control".into(), reason: e.to_string() })?;
        // The payload before the step rule: a mass off by a unit is named
        // as the payload beyond the rated thrust, not as the stiff rate it makes.
        self.plant.validate_fields()?;
        self.check_payload()?;
        self.plant.check_step_resolves_dynamics()
    }

    /// The heaviest payload this rig can carry hanging vertically: the
    /// motor must hold its weight indefinitely within the winding's
    /// continuous current, against the screw's back-drive torque
    /// `F L/2π (2 − 1/η)`, and a fitted brake must hold it when the drive
    /// is off. Kilograms, with the limiting part's name.
    pub fn payload_max_kg(&self) -> (f64, &'static str) {
        let p = &self.plant;
        let back_drive_m = p.metres_per_rad() * (2.0 - 1.0 / p.screw.efficiency);
        let k_t = 1.5 * f64::from(p.motor.pole_pairs) * p.motor.flux_linkage_wb;
        let motor_n = k_t * f64::from(self.control.thermal.continuous_current_a) / back_drive_m;
        let brake_n = if p.brake.fitted { p.brake.holding_torque_n_m / back_drive_m } else { f64::INFINITY };
        let (force, by) = if motor_n <= brake_n {
            (motor_n, "the motor's torque at control.thermal.continuous_current_a")
        } else {
            (brake_n, "plant.brake.holding_torque_n_m")
        };
        (force / p.load.gravity_m_s2.max(f64::MIN_POSITIVE) - p.rod.nut_rod_mass_kg, by)
    }

    fn check_payload(&self) -> std::result::Result<(), ParamError> {
        let (max_kg, by) = self.payload_max_kg();
        let payload = self.plant.rod.payload_mass_kg;
        if payload > max_kg {
            let weight = self.plant.moving_mass_kg() * self.plant.load.gravity_m_s2;
            return Err(ParamError {
                field: "plant.rod.payload_mass_kg".into(),
                reason: format!(
                    "{payload} kg is beyond the rated thrust: the moving mass weighs {weight:.0} N hanging vertically, \
                     more than {by} holds; must be <= {max_kg:.1} kg"
                ),
            });
        }
        Ok(())
    }

    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading rig file {}", path.display()))?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// The shipped rig (`host-sim/params/rig.toml`).
    pub fn nominal() -> Result<Self> {
        Self::from_toml(DEFAULT_RIG_TOML, "params/rig.toml")
    }

    /// `path` if given, else the shipped rig.
    pub fn load_or_nominal(path: Option<&PathBuf>) -> Result<Self> {
        match path {
            Some(p) => Self::load(p),
            None => Self::nominal(),
        }
    }
}
