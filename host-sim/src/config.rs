//! The rig description: one TOML file with the controller's parameters
//! (`[control]`, the very struct the firmware compiles) and the plant's
//! (`[plant]`). Validated on load; errors name the file and the field.

use crate::plant::PlantParams;
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
        cfg.control.validate().map_err(|e| anyhow!("{origin}: {e}"))?;
        cfg.plant.validate().map_err(|e| anyhow!("{origin}: {e}"))?;
        Ok(cfg)
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
