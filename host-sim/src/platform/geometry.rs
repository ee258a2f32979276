//! The platform's geometry (paper Table 3), loaded from TOML and validated.
//!
//! Conventions (docs/platform.md):
//! - Base frame: origin at the centre of the base joint circle, z up
//!   (against gravity), x forward. Platform frame: origin at the centre of
//!   the top joint circle, axes parallel to the base frame's at home.
//! - Joint layout: the base joints form three pairs centred at azimuths
//!   0°, 120°, 240°, the two joints of a pair α_b apart (the hexagon's short
//!   side); the top pairs are centred at 60°, 180°, 300°, α_p apart. Each leg
//!   runs from a base joint to the nearer joint of the neighbouring top pair,
//!   so the legs cross in the usual Stewart zig-zag.
//! - Numbering: leg 1 starts at the base joint at azimuth +α_b/2, then
//!   counter-clockwise seen from above (leg 2 at 120° − α_b/2, leg 3 at
//!   120° + α_b/2, …). Internally legs are indexed 0..6; messages say 1..6.

use anyhow::{anyhow, bail, Context, Result};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The shipped geometry (`host-sim/params/platform.toml`), the paper's Table 3.
pub const PAPER_GEOMETRY_TOML: &str = include_str!("../../params/platform.toml");

/// Smallest distance allowed between two joints of one plate.
pub const MIN_JOINT_SEPARATION_M: f64 = 1e-3;

/// Table 3, plus the inertia the paper does not give.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    pub top_radius_m: f64,
    pub base_radius_m: f64,
    pub top_short_side_angle_deg: f64,
    pub base_short_side_angle_deg: f64,
    /// Joint plane to joint plane at the home pose.
    pub home_height_m: f64,
    pub leg_min_length_m: f64,
    pub leg_max_length_m: f64,
    /// Table 3's l_0: the retracted length (checked within the limits).
    pub leg_initial_length_m: f64,
    pub payload_mass_kg: f64,
    /// Principal moments of plate + payload about its centre of mass, in
    /// the platform frame.
    pub payload_inertia_kg_m2: [f64; 3],
    /// Centre of mass of plate + payload in the platform frame.
    pub payload_com_m: [f64; 3],
    pub upper_leg_mass_kg: f64,
    pub lower_leg_mass_kg: f64,
}

/// Joint positions: `base[i]` in the base frame, `top[i]` in the platform
/// frame, for leg i (0-based).
#[derive(Clone, Debug, PartialEq)]
pub struct Joints {
    pub base: [Vector3<f64>; 6],
    pub top: [Vector3<f64>; 6],
}

impl Geometry {
    /// The paper's Table 3.
    pub fn paper() -> Self {
        Self::from_toml(PAPER_GEOMETRY_TOML, "params/platform.toml").expect("the shipped platform geometry is valid")
    }

    /// Parses and validates; `origin` names the text in errors.
    pub fn from_toml(text: &str, origin: &str) -> Result<Self> {
        let de = toml::Deserializer::parse(text).map_err(|e| anyhow!("{origin}: {e}"))?;
        let g: Geometry = serde_path_to_error::deserialize(de).map_err(|e| anyhow!("{origin}: `{}`: {}", e.path(), e.inner()))?;
        g.validate().map_err(|e| anyhow!("{origin}: {e}"))?;
        Ok(g)
    }

    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("reading platform geometry {}", path.display()))?;
        Self::from_toml(&text, &path.display().to_string())
    }

    /// Base (`base == true`) or top joint azimuths in radians, by leg.
    fn azimuths(short_side_deg: f64, base: bool) -> [f64; 6] {
        let half = short_side_deg.to_radians() / 2.0;
        let third = 120f64.to_radians();
        let sixth = 60f64.to_radians();
        std::array::from_fn(|i| {
            let pair = (i / 2) as f64;
            if base {
                // Leg 2j+1 (1-based) at c_j + α/2, leg 2j+2 at c_{j+1} − α/2.
                if i % 2 == 0 { pair * third + half } else { (pair + 1.0) * third - half }
            } else {
                // Both legs of base gap j meet the top pair centred at c_j + 60°.
                if i % 2 == 0 { pair * third + sixth - half } else { pair * third + sixth + half }
            }
        })
    }

    pub fn joints(&self) -> Joints {
        let on_circle = |r: f64, a: f64| Vector3::new(r * a.cos(), r * a.sin(), 0.0);
        let b = Self::azimuths(self.base_short_side_angle_deg, true);
        let t = Self::azimuths(self.top_short_side_angle_deg, false);
        Joints {
            base: std::array::from_fn(|i| on_circle(self.base_radius_m, b[i])),
            top: std::array::from_fn(|i| on_circle(self.top_radius_m, t[i])),
        }
    }

    /// Every leg's length at the home pose (equal by symmetry).
    pub fn home_leg_length_m(&self) -> f64 {
        let j = self.joints();
        (j.top[0] + Vector3::new(0.0, 0.0, self.home_height_m) - j.base[0]).norm()
    }

    pub fn inertia_body(&self) -> Matrix3<f64> {
        Matrix3::from_diagonal(&Vector3::from(self.payload_inertia_kg_m2))
    }

    pub fn com_body(&self) -> Vector3<f64> {
        Vector3::from(self.payload_com_m)
    }

    /// Refuses a layout no platform can have, naming the field.
    pub fn validate(&self) -> Result<()> {
        let positive = [
            ("top_radius_m", self.top_radius_m),
            ("base_radius_m", self.base_radius_m),
            ("home_height_m", self.home_height_m),
            ("leg_min_length_m", self.leg_min_length_m),
            ("leg_max_length_m", self.leg_max_length_m),
            ("leg_initial_length_m", self.leg_initial_length_m),
            ("payload_mass_kg", self.payload_mass_kg),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                bail!("`{name}` = {v}: must be finite and positive");
            }
        }
        for (name, v) in [("upper_leg_mass_kg", self.upper_leg_mass_kg), ("lower_leg_mass_kg", self.lower_leg_mass_kg)] {
            if !(v.is_finite() && v >= 0.0) {
                bail!("`{name}` = {v}: must be finite and not negative");
            }
        }
        if let Some(c) = self.payload_com_m.iter().find(|c| !c.is_finite()) {
            bail!("`payload_com_m`: component {c} is not finite");
        }
        let [ix, iy, iz] = self.payload_inertia_kg_m2;
        if [ix, iy, iz].iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            bail!("`payload_inertia_kg_m2` = {:?}: every principal moment must be finite and positive", self.payload_inertia_kg_m2);
        }
        if ix + iy < iz || iy + iz < ix || iz + ix < iy {
            bail!("`payload_inertia_kg_m2` = {:?}: violates the triangle inequality no rigid body can", self.payload_inertia_kg_m2);
        }
        for (name, r, a) in [
            ("top_short_side_angle_deg", self.top_radius_m, self.top_short_side_angle_deg),
            ("base_short_side_angle_deg", self.base_radius_m, self.base_short_side_angle_deg),
        ] {
            if !(a.is_finite() && a > 0.0 && a < 120.0) {
                bail!("`{name}` = {a}°: must lie strictly between 0° and 120° (at 0° the joints of a pair coincide, at 120° those of neighbouring pairs)");
            }
            // Chords of the short side (α) and the long side (120° − α).
            let short = 2.0 * r * (a.to_radians() / 2.0).sin();
            let long = 2.0 * r * ((120.0 - a).to_radians() / 2.0).sin();
            if short.min(long) < MIN_JOINT_SEPARATION_M {
                bail!(
                    "`{name}` = {a}°: joints {:.3} mm apart, closer than {} mm (coincident joints)",
                    short.min(long) * 1e3,
                    MIN_JOINT_SEPARATION_M * 1e3
                );
            }
        }
        if self.leg_min_length_m >= self.leg_max_length_m {
            bail!("`leg_min_length_m` = {} m is not below `leg_max_length_m` = {} m", self.leg_min_length_m, self.leg_max_length_m);
        }
        if self.leg_initial_length_m < self.leg_min_length_m || self.leg_initial_length_m > self.leg_max_length_m {
            bail!(
                "`leg_initial_length_m` = {} m lies outside [`leg_min_length_m`, `leg_max_length_m`] = [{}, {}] m",
                self.leg_initial_length_m,
                self.leg_min_length_m,
                self.leg_max_length_m
            );
        }
        let home = self.home_leg_length_m();
        if home < self.leg_min_length_m {
            bail!(
                "`home_height_m` = {} m: the legs cannot reach the home pose: it needs {home:.4} m, below `leg_min_length_m` = {} m",
                self.home_height_m,
                self.leg_min_length_m
            );
        }
        if home > self.leg_max_length_m {
            bail!(
                "`home_height_m` = {} m: the legs cannot reach the home pose: it needs {home:.4} m, above `leg_max_length_m` = {} m",
                self.home_height_m,
                self.leg_max_length_m
            );
        }
        Ok(())
    }
}
