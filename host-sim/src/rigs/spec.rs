//! What a rig family varies, and by how much: the tolerances a second unit
//! of the same cylinder may differ by, each a command-line option.

use crate::config::RigConfig;
use std::f64::consts::TAU;

/// Tolerances of a family, relative to the base rig. Each range is a pair
/// of factors (or, for the lead error, metres per metre).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FamilySpec {
    /// Structure stiffness: every axial and torsional compliance of the
    /// deformation and the coupling scaled by 1/(1 ± this).
    pub stiffness_tol: f64,
    /// Friction: Coulomb (seal, nut preload drag), viscous (rotor, screw
    /// bearings, seal) and the screw's friction coefficient μ = (1−η)/η,
    /// each drawn within ±this.
    pub friction_tol: f64,
    /// Payload, fraction of the base rig's (rated) payload.
    pub payload_min: f64,
    pub payload_max: f64,
    /// Rotor, coupling and screw inertia, ±this.
    pub inertia_tol: f64,
    /// Winding resistance factor range (cold to hot).
    pub resistance_min: f64,
    pub resistance_max: f64,
    /// d and q inductance, ±this.
    pub inductance_tol: f64,
    /// Magnet flux linkage factor range (hot magnets lose flux).
    pub flux_min: f64,
    pub flux_max: f64,
    /// Cumulative lead error, ±this (m/m).
    pub lead_error_max: f64,
}

/// A C7 ball screw's travel deviation: ±52 µm over any 300 mm (ISO 3408-3).
pub const C7_LEAD_ERROR_M_PER_M: f64 = 52.0e-6 / 0.3;

impl Default for FamilySpec {
    fn default() -> Self {
        Self {
            stiffness_tol: 0.15,
            friction_tol: 0.30,
            payload_min: 0.02,
            payload_max: 1.10,
            inertia_tol: 0.10,
            resistance_min: 0.90,
            resistance_max: 1.40,
            inductance_tol: 0.10,
            flux_min: 0.90,
            flux_max: 1.03,
            lead_error_max: C7_LEAD_ERROR_M_PER_M,
        }
    }
}

/// One rig's departure from the base: a factor per quantity (1: as the
/// base), the lead error and the encoder zero.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Draw {
    pub stiffness: f64,
    pub coulomb: f64,
    pub viscous: f64,
    pub screw_mu: f64,
    pub payload: f64,
    pub inertia: f64,
    pub resistance: f64,
    pub inductance: f64,
    pub flux: f64,
    pub lead_error_m_per_m: f64,
    pub encoder_zero_rad: f64,
}

impl Draw {
    /// The base rig itself.
    pub const BASE: Draw = Draw {
        stiffness: 1.0,
        coulomb: 1.0,
        viscous: 1.0,
        screw_mu: 1.0,
        payload: 1.0,
        inertia: 1.0,
        resistance: 1.0,
        inductance: 1.0,
        flux: 1.0,
        lead_error_m_per_m: 0.0,
        encoder_zero_rad: 0.0,
    };

    /// The five corners of issue-style robustness checks: a second unit
    /// with a softer or stiffer structure, a heavier payload, more
    /// friction, and softer + heavier + more friction together.
    pub fn corners(spec: &FamilySpec) -> [(&'static str, Draw); 5] {
        let softer = Draw { stiffness: 1.0 - spec.stiffness_tol, ..Draw::BASE };
        let stiffer = Draw { stiffness: 1.0 + spec.stiffness_tol, ..Draw::BASE };
        let heavier = Draw { payload: spec.payload_max, ..Draw::BASE };
        let f = 1.0 + spec.friction_tol;
        let friction = Draw { coulomb: f, viscous: f, screw_mu: f, ..Draw::BASE };
        let combined = Draw { stiffness: softer.stiffness, payload: spec.payload_max, ..friction };
        [
            ("corner_softer", softer),
            ("corner_stiffer", stiffer),
            ("corner_heavier", heavier),
            ("corner_friction", friction),
            ("corner_combined", combined),
        ]
    }

    /// A rig drawn uniformly within `spec`, encoder zero anywhere.
    pub fn random(spec: &FamilySpec, rng: &mut impl rand::Rng) -> Draw {
        let mut sym = |tol: f64| 1.0 + rng.random_range(-1.0..=1.0) * tol;
        let stiffness = sym(spec.stiffness_tol);
        let coulomb = sym(spec.friction_tol);
        let viscous = sym(spec.friction_tol);
        let screw_mu = sym(spec.friction_tol);
        let inertia = sym(spec.inertia_tol);
        let inductance = sym(spec.inductance_tol);
        let lead = rng.random_range(-1.0..=1.0) * spec.lead_error_max;
        Draw {
            stiffness,
            coulomb,
            viscous,
            screw_mu,
            payload: rng.random_range(spec.payload_min..=spec.payload_max),
            inertia,
            resistance: rng.random_range(spec.resistance_min..=spec.resistance_max),
            inductance,
            flux: rng.random_range(spec.flux_min..=spec.flux_max),
            lead_error_m_per_m: lead,
            encoder_zero_rad: rng.random_range(0.0..TAU),
        }
    }

    /// `base` with this draw applied to its `[plant]`; of `[control]`, the
    /// drive's belief, only the expected load at power-up follows the rig
    /// (a user states the load their cylinder carries).
    pub fn apply(&self, base: &RigConfig) -> RigConfig {
        let mut rig = base.clone();
        let p = &mut rig.plant;
        let s = self.stiffness;
        let d = &mut p.deformation;
        d.contact.coefficient_m_per_n2_3 /= s;
        d.screw_axial.youngs_modulus_pa *= s;
        d.rod.youngs_modulus_pa *= s;
        d.bearing.coefficient_m_per_n_k /= s;
        d.torsion.shear_modulus_pa *= s;
        p.coupling.torsional_stiffness_n_m_rad *= s;
        p.rod.coulomb_friction_n *= self.coulomb;
        p.rod.static_friction_n *= self.coulomb;
        p.screw.preload_drag_torque_n_m *= self.coulomb;
        p.rod.viscous_friction_n_s_m *= self.viscous;
        p.motor.viscous_friction_n_m_s_rad *= self.viscous;
        p.screw.viscous_friction_n_m_s_rad *= self.viscous;
        let mu = (1.0 - p.screw.efficiency) / p.screw.efficiency * self.screw_mu;
        p.screw.efficiency = 1.0 / (1.0 + mu);
        p.rod.payload_mass_kg *= self.payload;
        p.motor.rotor_inertia_kg_m2 *= self.inertia;
        p.coupling.inertia_kg_m2 *= self.inertia;
        p.screw.inertia_kg_m2 *= self.inertia;
        p.motor.phase_resistance_ohm *= self.resistance;
        p.motor.inductance_d_h *= self.inductance;
        p.motor.inductance_q_h *= self.inductance;
        p.motor.flux_linkage_wb *= self.flux;
        p.screw.lead_error_m_per_m += self.lead_error_m_per_m;
        p.sensors.encoder_zero_rad = self.encoder_zero_rad;
        // The one [control] value a user states for their own cylinder: the
        // load it carries at power-up (the hold vector is pointed for it).
        let load = p.moving_mass_kg() * p.load.gravity_m_s2 * p.load.initial_tilt_deg.to_radians().sin()
            + p.load.initial_external_force_n;
        rig.control.startup.expected_load_force_n = load as f32;
        rig
    }
}

/// A tolerance set that cannot give a valid family, naming the option.
#[derive(Debug)]
pub struct SpecError {
    pub option: String,
    pub reason: String,
}

impl std::fmt::Display for SpecError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.option, self.reason)
    }
}

impl std::error::Error for SpecError {}

/// The options of `FamilySpec` as ranges: the option that sets each end
/// (the same for a ± tolerance) and the draw there, everything else at
/// the base.
fn option_ends(spec: &FamilySpec) -> Vec<([&'static str; 2], [Draw; 2])> {
    let b = Draw::BASE;
    let (st, ft, it, lt) = (spec.stiffness_tol, spec.friction_tol, spec.inertia_tol, spec.inductance_tol);
    let friction = |f: f64| Draw { coulomb: f, viscous: f, screw_mu: f, ..b };
    vec![
        (["--stiffness-tol"; 2], [Draw { stiffness: 1.0 - st, ..b }, Draw { stiffness: 1.0 + st, ..b }]),
        (["--friction-tol"; 2], [friction(1.0 - ft), friction(1.0 + ft)]),
        (["--payload-min", "--payload-max"], [Draw { payload: spec.payload_min, ..b }, Draw { payload: spec.payload_max, ..b }]),
        (["--inertia-tol"; 2], [Draw { inertia: 1.0 - it, ..b }, Draw { inertia: 1.0 + it, ..b }]),
        (
            ["--resistance-min", "--resistance-max"],
            [Draw { resistance: spec.resistance_min, ..b }, Draw { resistance: spec.resistance_max, ..b }],
        ),
        (["--inductance-tol"; 2], [Draw { inductance: 1.0 - lt, ..b }, Draw { inductance: 1.0 + lt, ..b }]),
        (["--flux-min", "--flux-max"], [Draw { flux: spec.flux_min, ..b }, Draw { flux: spec.flux_max, ..b }]),
        (
            ["--lead-error-max"; 2],
            [
                Draw { lead_error_m_per_m: -spec.lead_error_max, ..b },
                Draw { lead_error_m_per_m: spec.lead_error_max, ..b },
            ],
        ),
    ]
}

impl FamilySpec {
    /// Refuses tolerances that are not numbers of the right sign and order,
    /// or that reach a rig the base file's bounds refuse: each option's
    /// own ends first (naming it), then every corner of the tolerance box
    /// together (naming the options at their ends there).
    pub fn check(&self, base: &RigConfig) -> Result<(), SpecError> {
        let err = |option: &str, reason: String| Err(SpecError { option: option.into(), reason });
        let fractions = [
            ("--stiffness-tol", self.stiffness_tol),
            ("--friction-tol", self.friction_tol),
            ("--inertia-tol", self.inertia_tol),
            ("--inductance-tol", self.inductance_tol),
        ];
        for (name, v) in fractions {
            if !(v.is_finite() && (0.0..1.0).contains(&v)) {
                return err(name, format!("{v} must be a fraction in [0, 1)"));
            }
        }
        let ranges = [
            ("--payload-min", "--payload-max", self.payload_min, self.payload_max),
            ("--resistance-min", "--resistance-max", self.resistance_min, self.resistance_max),
            ("--flux-min", "--flux-max", self.flux_min, self.flux_max),
        ];
        for (lo_name, hi_name, lo, hi) in ranges {
            if !(lo.is_finite() && lo > 0.0) {
                return err(lo_name, format!("{lo} must be a factor > 0"));
            }
            if !(hi.is_finite() && hi >= lo) {
                return err(hi_name, format!("{hi} must be finite and >= {lo_name} ({lo})"));
            }
        }
        if !(self.lead_error_max.is_finite() && self.lead_error_max >= 0.0) {
            return err("--lead-error-max", format!("{} must be >= 0", self.lead_error_max));
        }
        let ends = option_ends(self);
        for (names, draws) in &ends {
            for (name, d) in names.iter().zip(draws) {
                if let Err(e) = d.apply(base).validate() {
                    return err(name, format!("gives an invalid rig at the end of its range: {e}"));
                }
            }
        }
        // Every vertex of the box: options combine (a weak magnet and a
        // heavy payload, say).
        let k = ends.len();
        let vertex = |picks: &[Option<usize>]| {
            picks.iter().zip(&ends).fold(Draw::BASE, |d, (p, (_, draws))| p.map_or(d, |bit| merge(d, draws[bit])))
        };
        for mask in 0u32..(1 << k) {
            let mut picks: Vec<Option<usize>> = (0..k).map(|i| Some(((mask >> i) & 1) as usize)).collect();
            if vertex(&picks).apply(base).validate().is_ok() {
                continue;
            }
            // Name only the options the refusal needs: drop each whose
            // end the vertex still fails without.
            for i in 0..k {
                let kept = picks[i].take();
                if vertex(&picks).apply(base).validate().is_ok() {
                    picks[i] = kept;
                }
            }
            let e = vertex(&picks).apply(base).validate().err().map(|e| e.to_string()).unwrap_or_default();
            let named: Vec<&str> = picks.iter().zip(&ends).filter_map(|(p, (names, _))| p.map(|bit| names[bit])).collect();
            return err(&named.join(" with "), format!("together give an invalid rig at the ends of their ranges: {e}"));
        }
        Ok(())
    }
}

/// `a` with every quantity `b` changes from the base taken from `b`.
fn merge(a: Draw, b: Draw) -> Draw {
    let pick = |x: f64, y: f64, base: f64| if y != base { y } else { x };
    let o = Draw::BASE;
    Draw {
        stiffness: pick(a.stiffness, b.stiffness, o.stiffness),
        coulomb: pick(a.coulomb, b.coulomb, o.coulomb),
        viscous: pick(a.viscous, b.viscous, o.viscous),
        screw_mu: pick(a.screw_mu, b.screw_mu, o.screw_mu),
        payload: pick(a.payload, b.payload, o.payload),
        inertia: pick(a.inertia, b.inertia, o.inertia),
        resistance: pick(a.resistance, b.resistance, o.resistance),
        inductance: pick(a.inductance, b.inductance, o.inductance),
        flux: pick(a.flux, b.flux, o.flux),
        lead_error_m_per_m: pick(a.lead_error_m_per_m, b.lead_error_m_per_m, o.lead_error_m_per_m),
        encoder_zero_rad: pick(a.encoder_zero_rad, b.encoder_zero_rad, o.encoder_zero_rad),
    }
}
