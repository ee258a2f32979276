//! The benchmark's rigs, built from the base rig file: a second unit of
//! the cylinder as each tolerance of issue-style robustness checks makes it.

use crate::config::RigConfig;
use crate::rigs::spec::Draw;

/// Lead error of the lead rigs: 50 µm over 300 mm of travel.
pub const LEAD_ERROR_M_PER_M: f64 = 50.0e-6 / 0.3;

/// One rig of the benchmark: its name and its departure from the base.
#[derive(Clone, Debug)]
pub struct BenchRig {
    pub name: &'static str,
    pub draw: Draw,
    pub rig: RigConfig,
    /// Seeds of the rig's identification and logs (`seed`, `seed + 1 …`),
    /// apart from the evaluation's.
    pub seed: u64,
}

/// Every rig, in table order: nominal, stiffness −15 %/+15 %, friction
/// +30 % (Coulomb, viscous and the screw's μ), payload −10 %/+10 %, lead
/// error ∓50 µm/300 mm, and softer + heavier + more friction + lead
/// together.
pub fn bench_rigs(base: &RigConfig) -> Vec<BenchRig> {
    let b = Draw::BASE;
    let friction = |f: f64| Draw { coulomb: f, viscous: f, screw_mu: f, ..b };
    let combined = Draw { stiffness: 0.85, payload: 1.10, lead_error_m_per_m: LEAD_ERROR_M_PER_M, ..friction(1.30) };
    let draws = [
        ("nominal", b),
        ("stiffness_-15pct", Draw { stiffness: 0.85, ..b }),
        ("stiffness_+15pct", Draw { stiffness: 1.15, ..b }),
        ("friction_+30pct", friction(1.30)),
        ("payload_-10pct", Draw { payload: 0.90, ..b }),
        ("payload_+10pct", Draw { payload: 1.10, ..b }),
        ("lead_-50um_per_300mm", Draw { lead_error_m_per_m: -LEAD_ERROR_M_PER_M, ..b }),
        ("lead_+50um_per_300mm", Draw { lead_error_m_per_m: LEAD_ERROR_M_PER_M, ..b }),
        ("combined", combined),
    ];
    draws.into_iter().enumerate().map(|(i, (name, draw))| BenchRig { name, draw, rig: draw.apply(base), seed: 7000 + 10 * i as u64 }).collect()
}

/// The shipped weights' bar on a rig (max terminal error reduction, %),
/// `None` where none is asked (lead, combined: only retraining is).
pub fn shipped_bar_pct(name: &str) -> Option<f64> {
    match name {
        "nominal" => Some(90.0),
        "stiffness_-15pct" | "stiffness_+15pct" => Some(80.0),
        "friction_+30pct" | "payload_-10pct" | "payload_+10pct" => Some(88.0),
        _ => None,
    }
}

/// Weights retrained from the rig's own logs: 90 % on every rig.
pub const RETRAINED_BAR_PCT: f64 = 90.0;
