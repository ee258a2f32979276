//! The rig-mismatch explanation: the nominal's own parameters re-fitted
//! on the training part of the log and scored on the held-out part.
//!
//! A wrong rig file (or, against a healthy reference, a rig whose
//! parameters changed) is explained by re-fitting what the nominal already
//! holds — torque constant, moving mass, friction, compliance, flux — and
//! leaves a smooth residual locked to the motion. An unmeasured force with
//! a time course leaves change points no re-fit removes. The verdict
//! compares this explanation with the disturbance's (`verdict`).
//!
//! No regressor is built from a channel's own measured output: on the
//! torque channel the torque-constant error multiplies the *nominal*
//! torque (computed from the motion and the logged load), not the logged
//! current.

use super::figures::shrink;
use super::fit::{self, ChannelPred};
use super::residual::{reg_features, Nominal, Segment, CHANNELS, NCH, POSITION, TORQUE, VOLTAGE};
use std::collections::BTreeMap;

/// A re-fitted parameter counts as changed beyond this relative change
/// (torque constant, flux, moving mass: a calibrated drive and a weighed
/// payload are within a few %; the back-EMF gate's 15 % holds a 100 K
/// warm-up). Friction and compliance vary more from rig to rig (a new
/// seal, a preload): those count beyond `LOOSE_TOLERANCE`.
pub const TIGHT_TOLERANCE: f64 = 0.1;
pub const LOOSE_TOLERANCE: f64 = 0.5;
/// A regression coefficient (or group of coupled coefficients,
/// `refit_joint`) counts as changed when its held-out contribution (RMS of
/// the change × its regressor) reaches this share of the reference
/// nominal's own prediction (RMS), beyond its joint uncertainty.
pub const REGRESSION_CHANGE_SHARE: f64 = 0.1;
/// The constant force and the weight of the moving-mass change agree
/// within this share when the payload is what the rig file got wrong.
pub const PAYLOAD_WEIGHT_AGREEMENT: f64 = 0.3;
/// The re-fit is stable when, fitted on either half of the training
/// part, it keeps this share of its held-out primary-channel shrink.
pub const STABLE_SHARE: f64 = 0.7;
/// ... or loses at most this many points of it.
pub const STABLE_POINTS: f64 = 5.0;

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Refit {
    /// Re-fitted parameters, in physical units (rig file value → log).
    pub params: BTreeMap<String, (f64, f64)>,
    /// The parameters beyond their tolerance, with file and log values.
    pub changed: Vec<String>,
    /// Only a constant force changed: no rig parameter, an unmeasured
    /// constant force (its level in `params`).
    pub only_constant_force: bool,
    /// The moving mass changed and the constant force is that change's
    /// weight (within `PAYLOAD_WEIGHT_AGREEMENT`): a payload error.
    pub payload_consistent: bool,
    /// A parameter changed that only the rig file holds (torque constant,
    /// flux, compliance, a payload): no library effect stands for it.
    pub rig_specific: bool,
    pub constant_force_n: f64,
    /// The constant's level as the headline states it, in the channel's
    /// units (N at the nut with the rig's physics; the logged current or
    /// the tracking error with a regression nominal).
    pub constant_level: String,
    /// Held-out figures (`figures::PRIMARY`, `figures::WEIGHTED`).
    pub primary_shrink_pct: f64,
    pub weighted_shrink_pct: f64,
    pub shrink_by_channel: BTreeMap<String, f64>,
    /// Training Fit % per channel with the re-fit subtracted.
    pub train_fit_after: BTreeMap<String, f64>,
    /// Held-out primary-channel shrink of the re-fit on each half of the
    /// training part alone, and whether it keeps `STABLE_SHARE`.
    pub halves_primary_shrink_pct: (f64, f64),
    pub stable: bool,
    /// The coefficients per channel (on `features`).
    #[serde(skip)]
    pub coef: [Vec<f64>; NCH],
}

/// The re-fit's prediction of a segment's residuals.
pub fn predict_on(r: &Refit, s: &Segment, nominal: &Nominal) -> ChannelPred {
    predict(&r.coef, s, nominal)
}

/// Regressors of channel `c` at sample `i` (empty: channel not re-fitted).
fn features(s: &Segment, c: usize, i: usize, nominal: &Nominal) -> Vec<f64> {
    let nominal_pred = |c: usize| match (&s.y[c], &s.r[c]) {
        (Some(y), Some(r)) => y[i] - r[i],
        _ => 0.0,
    };
    match nominal {
        Nominal::Physics(p) => match c {
            // Nominal torque (torque-constant ratio), the moving mass's
            // inertia, a constant nut force, drag, viscous friction.
            TORQUE => vec![nominal_pred(TORQUE), p.k * s.a[i], p.k, s.friction_sign(p, i), s.omega[i]],
            // The nominal deflection (compliance ratio), and the deflection
            // a changed moving mass and a constant force leave through the
            // local compliance (the load offset's `−∂δ/∂F`).
            POSITION => vec![nominal_pred(POSITION), -s.c_loc[i] * s.a[i], -s.c_loc[i]],
            // Back-EMF (flux ratio), resistance, the inverter's dead time
            // (fitted alongside, as in the back-EMF gate).
            VOLTAGE => vec![
                p.pole_pairs * s.omega[i] * p.flux_wb,
                s.iq[i],
                (s.iq[i] / 0.1).tanh(),
            ],
            _ => Vec::new(),
        },
        Nominal::Regression(r) => match c {
            TORQUE | POSITION => reg_features(s, i, s.f_load[i], r.v_eps).to_vec(),
            _ => Vec::new(),
        },
    }
}

/// Weighted least squares of channel `c`'s residual on its regressors,
/// the first `fixed.len()` coefficients held at `fixed` (their part of
/// the prediction taken off the residual first).
fn solve_channel(segs: &[&Segment], nominal: &Nominal, c: usize, fixed: &[f64]) -> Vec<f64> {
    let Some(p) = segs
        .iter()
        .find(|s| s.r[c].is_some() && !s.is_empty())
        .map(|s| features(s, c, 0, nominal).len())
        .filter(|p| *p > fixed.len())
    else {
        return Vec::new();
    };
    let k = fixed.len();
    let q = p - k;
    let mut ata = nalgebra::DMatrix::<f64>::zeros(q, q);
    let mut atb = nalgebra::DVector::<f64>::zeros(q);
    for s in segs {
        let Some(r) = &s.r[c] else { continue };
        for (i, ri) in r.iter().enumerate() {
            let w2 = s.weight(c, i).powi(2);
            let f = features(s, c, i, nominal);
            let y = ri - f[..k].iter().zip(fixed).map(|(a, b)| a * b).sum::<f64>();
            for a in 0..q {
                atb[a] += w2 * f[k + a] * y;
                for b in 0..q {
                    ata[(a, b)] += w2 * f[k + a] * f[k + b];
                }
            }
        }
    }
    let d = ata
        .diagonal()
        .map(|v| if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 });
    let dm = nalgebra::DMatrix::from_diagonal(&d);
    let beta = (&dm * &ata * &dm)
        .svd(true, true)
        .solve(&(&dm * &atb), 1e-10)
        .unwrap_or_else(|_| nalgebra::DVector::zeros(q));
    fixed.iter().copied().chain((dm * beta).iter().copied()).collect()
}

/// Weighted least squares of the torque channel's residual, the nominal
/// torque's coefficient held at `ct`, on `extra(s, i)` plus drag and
/// viscous friction; returns the weighted RMS it leaves and the first
/// extra coefficient.
fn torque_alternative(
    segs: &[&Segment],
    p: &super::residual::Physics,
    ct: f64,
    extra: &dyn Fn(&Segment, usize) -> f64,
) -> (f64, f64) {
    let feats = |s: &Segment, i: usize| [extra(s, i), s.friction_sign(p, i), s.omega[i]];
    let nominal_torque = |s: &Segment, i: usize| match (&s.y[TORQUE], &s.r[TORQUE]) {
        (Some(y), Some(r)) => y[i] - r[i],
        _ => 0.0,
    };
    let mut ata = nalgebra::Matrix3::<f64>::zeros();
    let mut atb = nalgebra::Vector3::<f64>::zeros();
    for s in segs {
        let Some(r) = &s.r[TORQUE] else { continue };
        for (i, ri) in r.iter().enumerate() {
            let w2 = s.weight(TORQUE, i).powi(2);
            let f = feats(s, i);
            let y = ri - ct * nominal_torque(s, i);
            for a in 0..3 {
                atb[a] += w2 * f[a] * y;
                for b in 0..3 {
                    ata[(a, b)] += w2 * f[a] * f[b];
                }
            }
        }
    }
    let beta = ata
        .svd(true, true)
        .solve(&atb, 1e-12)
        .unwrap_or_else(|_| nalgebra::Vector3::zeros());
    let (mut ss, mut n) = (0.0, 0.0);
    for s in segs {
        let Some(r) = &s.r[TORQUE] else { continue };
        for (i, ri) in r.iter().enumerate() {
            let f = feats(s, i);
            let e = ri - ct * nominal_torque(s, i) - (0..3).map(|a| beta[a] * f[a]).sum::<f64>();
            ss += (s.weight(TORQUE, i) * e).powi(2);
            n += 1.0;
        }
    }
    ((ss / f64::max(n, 1.0)).sqrt(), beta[0])
}

/// The re-fit on `segs`. With the rig's physics and a logged voltage, the
/// torque constant is not fitted on the torque channel but follows the
/// flux the back-EMF gives (`K_t = 1.5 p ψ_f`): fitted on the torque alone
/// it is collinear with the moving mass, the weight and the friction
/// whenever the logged load does not vary (the nominal torque is then
/// their sum), and a force event drives it anywhere.
fn solve(segs: &[&Segment], nominal: &Nominal) -> [Vec<f64>; NCH] {
    let voltage = solve_channel(segs, nominal, VOLTAGE, &[]);
    let torque = match (nominal, voltage.first()) {
        (Nominal::Physics(_), Some(ce)) => {
            // K_file i = (K_file / K_log) T: the nominal torque's coefficient
            // is K_file / K_log − 1 = 1 / (1 + ce) − 1.
            solve_channel(segs, nominal, TORQUE, &[1.0 / (1.0 + ce) - 1.0])
        }
        _ => solve_channel(segs, nominal, TORQUE, &[]),
    };
    [torque, solve_channel(segs, nominal, POSITION, &[]), voltage]
}

/// The re-fit's prediction of one segment's residuals.
pub fn predict(coef: &[Vec<f64>; NCH], s: &Segment, nominal: &Nominal) -> ChannelPred {
    std::array::from_fn(|c| {
        let r = s.r[c].as_ref()?;
        if coef[c].is_empty() {
            return Some(vec![0.0; r.len()]);
        }
        Some(
            (0..r.len())
                .map(|i| {
                    features(s, c, i, nominal)
                        .iter()
                        .zip(&coef[c])
                        .map(|(a, b)| a * b)
                        .sum()
                })
                .collect(),
        )
    })
}

/// Re-fits the nominal on `train`, scores it on `held`. Returns the
/// figures and the held-out prediction (per held-out segment).
pub fn fit(
    train: &[&Segment],
    held: &[&Segment],
    nominal: &Nominal,
    w: &[f64; NCH],
    primary: usize,
) -> (Refit, Vec<ChannelPred>) {
    let coef = solve(train, nominal);
    let pred_h: Vec<ChannelPred> = held.iter().map(|s| predict(&coef, s, nominal)).collect();
    let pred_t: Vec<ChannelPred> = train.iter().map(|s| predict(&coef, s, nominal)).collect();
    let mut wp = [0.0; NCH];
    wp[primary] = 1.0;
    let primary_shrink = |p: &[ChannelPred]| shrink(fit::gap(held, None, &wp), fit::gap(held, Some(p), &wp));
    let mut out = Refit {
        primary_shrink_pct: primary_shrink(&pred_h),
        weighted_shrink_pct: shrink(fit::gap(held, None, w), fit::gap(held, Some(&pred_h), w)),
        ..Default::default()
    };
    for c in 0..NCH {
        let mut wc = [0.0; NCH];
        wc[c] = 1.0;
        if held.iter().any(|s| s.r[c].is_some()) {
            out.shrink_by_channel.insert(
                CHANNELS[c].into(),
                shrink(fit::gap(held, None, &wc), fit::gap(held, Some(&pred_h), &wc)),
            );
        }
    }
    for (c, f) in fit::fit_pct(train, Some(&pred_t)).iter().enumerate() {
        if let Some(f) = f {
            out.train_fit_after.insert(CHANNELS[c].into(), *f);
        }
    }
    // Stability: each half of every training segment alone.
    let halves: [Vec<Segment>; 2] = std::array::from_fn(|h| {
        train
            .iter()
            .map(|s| {
                let mid = s.len() / 2;
                let (a, b) = if h == 0 { (0, mid) } else { (mid, s.len()) };
                super::slice_segment(s, a, b, false)
            })
            .collect()
    });
    let half_shrink = |segs: &Vec<Segment>| {
        let refs: Vec<&Segment> = segs.iter().filter(|s| !s.is_empty()).collect();
        let c = solve(&refs, nominal);
        let p: Vec<ChannelPred> = held.iter().map(|s| predict(&c, s, nominal)).collect();
        primary_shrink(&p)
    };
    out.halves_primary_shrink_pct = (half_shrink(&halves[0]), half_shrink(&halves[1]));
    let (a, b) = out.halves_primary_shrink_pct;
    // A small shrink kept within a few points by both halves is stable too
    // (70 % of 6 % is noise, not drift).
    out.stable = out.primary_shrink_pct > 0.0
        && (a.min(b) >= STABLE_SHARE * out.primary_shrink_pct
            || (out.primary_shrink_pct - a.min(b)) <= STABLE_POINTS);
    describe(&mut out, &coef, train, held, nominal);
    out.coef = coef;
    (out, pred_h)
}

/// Physical parameters from the coefficients, and which changed.
fn describe(out: &mut Refit, coef: &[Vec<f64>; NCH], train: &[&Segment], held: &[&Segment], nominal: &Nominal) {
    let mut changed = Vec::new();
    fn put(changed: &mut Vec<String>, out: &mut Refit, name: &str, file: f64, log: f64, tol: f64) {
        out.params.insert(name.into(), (file, log));
        let rel = if file != 0.0 { (log - file) / file } else { f64::INFINITY };
        if rel.abs() > tol {
            changed.push(format!("{name} {file:.4e} → {log:.4e} ({:+.0} %)", 100.0 * rel));
        }
    }
    match nominal {
        Nominal::Physics(p) => {
            let mut const_force = 0.0;
            if let [ct, cm, cf, cd, cb] = coef[TORQUE][..] {
                // K_file i = (1 + ct) T_nom + ...: the log's torque constant is
                // K_file / (1 + ct); the other terms are in the file's units,
                // so each is divided by (1 + ct) to be in the log's torque.
                let s = 1.0 + ct;
                put(&mut changed, out, "torque_constant_n_m_per_a", p.kt, p.kt / s, TIGHT_TOLERANCE);
                put(&mut changed, out, "moving_mass_kg", p.m_moving, p.m_moving + cm / s, TIGHT_TOLERANCE);
                put(&mut changed, out, "nut_drag_torque_n_m", p.drag_n_m, p.drag_n_m + cd / s, LOOSE_TOLERANCE);
                put(&mut changed, out, "viscous_friction_n_m_s_rad", p.b_rot, p.b_rot + cb / s, LOOSE_TOLERANCE);
                const_force = cf / s;
                out.params.insert("constant_nut_force_n".into(), (0.0, const_force));
                // A constant force "changes" when it is a tenth of the
                // nominal nut force's RMS (over the training part).
                let (mut ss, mut n) = (0.0, 0.0);
                for s in train {
                    for f in &s.f_ax {
                        ss += f * f;
                        n += 1.0;
                    }
                }
                let f_rms = (ss / f64::max(n, 1.0)).sqrt();
                if const_force.abs() > TIGHT_TOLERANCE * f_rms {
                    changed.push(format!(
                        "constant_nut_force_n 0 → {const_force:.1} N ({:.0} % of the nominal nut force's RMS {f_rms:.0} N)",
                        100.0 * const_force.abs() / f_rms.max(1e-9)
                    ));
                }
            }
            if let [cc, _, _] = coef[POSITION][..] {
                put(&mut changed, out, "compliance_ratio", 1.0, 1.0 + cc, LOOSE_TOLERANCE);
            }
            if let [ce, cr, _] = coef[VOLTAGE][..] {
                put(&mut changed, out, "flux_linkage_wb", p.flux_wb, p.flux_wb * (1.0 + ce), TIGHT_TOLERANCE);
                put(&mut changed, out, "phase_resistance_ohm", p.r_ohm, p.r_ohm + cr, LOOSE_TOLERANCE);
            }
            out.constant_force_n = const_force;
            out.only_constant_force =
                changed.len() == 1 && changed[0].starts_with("constant_nut_force_n");
            out.constant_level = format!("{const_force:.1} N at the nut");
            // A payload error on a tilted axis changes the weight with the
            // inertia: the constant force is the mass change's weight.
            let (m_file, m_log) = out.params.get("moving_mass_kg").copied().unwrap_or((0.0, 0.0));
            let g_axial = p.gravity * p.tilt_deg.to_radians().sin();
            let weight = (m_log - m_file) * g_axial;
            let agrees = changed.iter().any(|c| c.starts_with("moving_mass_kg"))
                && weight.abs() > 0.0
                && (const_force - weight).abs() <= PAYLOAD_WEIGHT_AGREEMENT * weight.abs();
            // The inertia of a small mass change is a weak signal next to
            // its weight, so the free mass can miss while the constant
            // force is right. Two one-parameter explanations of the same
            // complexity then decide on training: a payload (one mass
            // change that is both weight and inertia, `k (a + g sin tilt)`)
            // or a constant force (`k`). The payload is what the rig file
            // got wrong when it fits better and its mass change is beyond
            // tolerance.
            let ct = coef[TORQUE].first().copied().unwrap_or(0.0);
            let s1 = 1.0 + ct;
            let (gap_payload, dm) = torque_alternative(train, p, ct, &|s, i| p.k * (s.a[i] + g_axial));
            let (gap_force, _) = torque_alternative(train, p, ct, &|_, _| p.k);
            let dm = dm / s1;
            // The inertia must say so too: the free mass changed beyond
            // tolerance the same way (a constant force leaves it alone; a
            // floor that follows the acceleration would favour the payload
            // model by itself).
            let mass_moved_same_way = changed.iter().any(|c| c.starts_with("moving_mass_kg"))
                && (m_log - m_file) * dm > 0.0;
            let payload_better = g_axial.abs() > 0.0
                && gap_payload < gap_force
                && dm.abs() > TIGHT_TOLERANCE * p.m_moving
                && mass_moved_same_way;
            out.params.insert("payload_mass_change_kg".into(), (0.0, dm));
            out.payload_consistent = agrees || payload_better;
            out.rig_specific = out.payload_consistent
                || changed.iter().any(|c| {
                    c.starts_with("torque_constant") || c.starts_with("flux_linkage") || c.starts_with("compliance_ratio")
                });
        }
        Nominal::Regression(r) => {
            for (c, base) in [(TORQUE, &r.torque_coef), (POSITION, &r.position_coef)] {
                if coef[c].is_empty() {
                    continue;
                }
                // Each group's change against the reference nominal's
                // prediction (RMS over the held-out part), judged with its
                // joint uncertainty (`refit_joint`).
                let (mut nom, mut n) = (0.0, 0.0);
                for s in held {
                    for i in 0..s.len() {
                        let f = reg_features(s, i, s.f_load[i], r.v_eps);
                        let y: f64 = f.iter().zip(base.iter()).map(|(a, b)| a * b).sum();
                        nom += y * y;
                        n += 1.0;
                    }
                }
                let nom = (nom / f64::max(n, 1.0)).sqrt();
                for (j, name) in super::residual::REG_FEATURES.iter().enumerate() {
                    out.params.insert(format!("{}[{name}]", CHANNELS[c]), (base[j], base[j] + coef[c][j]));
                }
                let unit = if c == TORQUE { "A in the logged current" } else { "m in the tracking error" };
                for g in super::refit_joint::group_changes(train, held, r, c, base, &coef[c]) {
                    if g.name.ends_with("[1]") {
                        let level = format!("{:.3e} {unit}", g.refit - g.base);
                        out.constant_level = if out.constant_level.is_empty() { level } else { format!("{}, {level}", out.constant_level) };
                    }
                    out.params.insert(g.name.clone(), (g.base, g.refit));
                    if g.changed(nom, REGRESSION_CHANGE_SHARE) {
                        changed.push(format!(
                            "{} {:.3e} → {:.3e} ± {:.1e} (its change {:.0} % of the nominal's RMS)",
                            g.name,
                            g.base,
                            g.refit,
                            g.sd,
                            100.0 * g.effect_rms / nom
                        ));
                    }
                }
            }
        }
    }
    // A regression re-fit that moves only the constant terms is an
    // unmeasured constant load (or offset), as a constant force is with the
    // rig's physics: no coefficient of the healthy rig changed.
    if matches!(nominal, Nominal::Regression(_)) {
        out.only_constant_force = !changed.is_empty() && changed.iter().all(|c| c.split(' ').next().is_some_and(|n| n.ends_with("[1]")));
    }
    out.changed = changed;
}
