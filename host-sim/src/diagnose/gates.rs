//! Baseline gates: checks on the nominal and on the data
//! that come before any finding, each with its figures.

use super::log::Log;
use super::residual::{Nominal, Segment, CHANNELS, NCH, TORQUE, VOLTAGE};
use super::summary::NotRanked;

/// Training Fit % of a channel below which the nominal "explains the
/// training data poorly". On the truth rigs of the full plant the nominal
/// reaches 75–99 % (torque, voltage) and 40–80 % (position, a few µm of
/// deflection against a µm floor); a log against the wrong rig falls far
/// below, and a negative Fit means the nominal is worse than the mean.
pub const NOMINAL_FIT_MIN_PCT: [f64; NCH] = [50.0, 0.0, 50.0];

/// Held-out Fit % this many points below the training Fit %: the held-out
/// run is not like the training run (another load, rig state or an event
/// the training part did not have).
pub const HELDOUT_DROP_POINTS: f64 = 20.0;

/// The logged torque against the torque the rig's physics needs, as the
/// least-squares scale `a` in `K_t i ≈ a · T_nominal`: outside `1 ± this`
/// the torque constant, lead or inertia of the rig file do not match the
/// log (a current-sensor gain error of a calibrated drive is a few %).
pub const TORQUE_SCALE_TOLERANCE: f64 = 0.2;

/// The logged back-EMF against the rig file's, as the least-squares scale
/// `k` in `u_q − R i_q − L_q di_q/dt ≈ k · p ω ψ_f`: outside `1 ± this`
/// the rig file's flux linkage is not this motor's. Only the flux enters
/// it (no mass, lead or friction), and NdFeB loses 0.12 %/K, ≤ 12 % over
/// a 100 K warm-up; a torque constant checked through the torque scale
/// alone can be hidden by a payload error of the opposite sign.
pub const BACK_EMF_TOLERANCE: f64 = 0.15;

/// Implausible library fits (`plausible`) from this many effects mean the
/// log does not match the rig's physics, not that the rig has them all.
pub const IMPLAUSIBLE_FITS_MISMATCH: usize = 2;

#[derive(Clone, Debug, serde::Serialize)]
pub struct Gate {
    /// `nominal_poor_fit`, `physics_mismatch`, `implausible_fits`, `heldout_drop`,
    /// `heldout_is_training`, `training_is_reference`, `heldout_is_reference`.
    pub kind: String,
    pub channel: Option<String>,
    pub message: String,
    /// The figure the gate fired on (Fit %, scale, count).
    pub figure: f64,
}

/// The note that the training log is the reference and the held-out log
/// is diagnosed alone, cut between its events.
pub fn training_is_reference_split(log: &Log, heldout: &Log) -> Gate {
    Gate {
        kind: "training_is_reference_split".into(),
        channel: None,
        message: format!(
            "the training log `{}` is the reference the nominal was fitted on, so nothing can be trained on it: the held-out log `{}` is diagnosed on its own, cut between its events, alternate pieces training and scoring (the disturbance's choices and every fit made on half its events, scored on the other half)",
            log.source, heldout.source
        ),
        figure: 1.0,
    }
}

/// Gates after which no cause is named: the nominal is unsound on what it
/// was fitted on (`reference_unsound`). The diagnosed log's own fit never
/// breaks the baseline — a poor or negative Fit there is what a large gap
/// looks like, whatever its cause (`verdict` weighs the explanations).
pub fn baseline_broken(g: &Gate) -> bool {
    g.kind == "reference_unsound"
}

/// Regression nominal: the reference's held-out Fit % (the regression
/// fitted on one half of the reference's runs, scored on the other, both
/// ways) at or below this means the nominal explains nothing of its own
/// healthy data beyond the mean.
pub const REFERENCE_HELDOUT_FIT_MIN_PCT: f64 = 0.0;
/// ... or this many points below its in-sample Fit: it over-fits the
/// reference, so a log's gap against it is the regression's, not the rig's.
pub const REFERENCE_DROP_POINTS: f64 = 20.0;

/// The regression nominal judged on what it was fitted on: its in-sample
/// Fit on the reference and its held-out Fit on halves of the reference
/// (alternate runs, or the two halves in time of a single run).
/// `reference_unsound` blocks every cause; `reference_poor_fit` (in-sample
/// Fit under `NOMINAL_FIT_MIN_PCT`, held-out as good) is a warning: the
/// healthy rig's own scatter is the floor every figure is relative to.
pub fn reference_gates(reference: &Log, reg: &super::residual::Regression) -> anyhow::Result<Vec<Gate>> {
    use super::residual::{build_segments, fit_regression_segments, regression_fit_pct, zero_regression};
    let segs = build_segments(reference, &Nominal::Regression(zero_regression()), 0.0)?;
    let parts: [Vec<Segment>; 2] = if segs.len() >= 2 {
        std::array::from_fn(|h| segs.iter().skip(h).step_by(2).cloned().collect())
    } else {
        std::array::from_fn(|h| {
            segs.iter()
                .map(|s| {
                    let mid = s.len() / 2;
                    let (a, b) = if h == 0 { (0, mid) } else { (mid, s.len()) };
                    super::slice_segment(s, a, b, false)
                })
                .collect()
        })
    };
    fn refs(v: &[Segment]) -> Vec<&Segment> {
        v.iter().filter(|s| !s.is_empty()).collect()
    }
    let all = refs(&segs);
    let inside = regression_fit_pct(reg, &all);
    let fits: [[Option<f64>; 2]; 2] = std::array::from_fn(|h| {
        let r = fit_regression_segments(&refs(&parts[h]));
        regression_fit_pct(&r, &refs(&parts[1 - h]))
    });
    let mut out = Vec::new();
    for (k, c) in [TORQUE, super::residual::POSITION].into_iter().enumerate() {
        let (Some(fi), Some(a), Some(b)) = (inside[k], fits[0][k], fits[1][k]) else {
            continue;
        };
        let held = 0.5 * (a + b);
        let name = if c == TORQUE { "current" } else { "tracking error" };
        if held <= REFERENCE_HELDOUT_FIT_MIN_PCT || fi - held > REFERENCE_DROP_POINTS {
            out.push(Gate {
                kind: "reference_unsound".into(),
                channel: Some(CHANNELS[c].into()),
                message: format!(
                    "the regression nominal does not hold on its own reference `{}`: {name} Fit {fi:.1} % in-sample, {held:.1} % on the half of the reference it was not fitted on (held-out gate > {REFERENCE_HELDOUT_FIT_MIN_PCT:.0} %, drop gate {REFERENCE_DROP_POINTS:.0} points); a gap against it is the regression's, not the rig's",
                    reference.source
                ),
                figure: held,
            });
        } else if fi < NOMINAL_FIT_MIN_PCT[c] {
            out.push(Gate {
                kind: "reference_poor_fit".into(),
                channel: Some(CHANNELS[c].into()),
                message: format!(
                    "the regression nominal explains the {name} of its own reference `{}` only partly: Fit {fi:.1} % in-sample, {held:.1} % on held-out halves (as good: the nominal is sound, the healthy rig's own scatter is the floor every figure is relative to)",
                    reference.source
                ),
                figure: fi,
            });
        }
    }
    Ok(out)
}

/// Whether two logs carry the same data (every common column equal to
/// 1e-12 relative, at least two columns in common).
pub fn same_data(a: &Log, b: &Log) -> bool {
    if a.len() != b.len() || a.is_empty() {
        return false;
    }
    let common: Vec<&String> = a
        .columns
        .keys()
        .filter(|k| b.columns.contains_key(*k))
        .collect();
    common.len() >= 2
        && common.iter().all(|k| {
            a.columns[*k].iter().zip(&b.columns[*k]).all(|(x, y)| {
                (x - y).abs() <= 1e-12 * x.abs().max(y.abs()).max(1e-300)
                    || (x.is_nan() && y.is_nan())
            })
        })
}

/// Identity gates between training, held-out and reference logs.
pub fn identity(log: &Log, heldout: Option<&Log>, reference: Option<&Log>) -> Vec<Gate> {
    let mut out = Vec::new();
    let g = |kind: &str, message: String| Gate {
        kind: kind.into(),
        channel: None,
        message,
        figure: 1.0,
    };
    if let Some(h) = heldout {
        if same_data(log, h) {
            out.push(g("heldout_is_training", format!(
                "the held-out log `{}` carries the same data as the training log `{}`: every held-out figure is a training figure, so over-fitting and run-to-run change are not ruled out; no effect is named",
                h.source, log.source
            )));
        }
        if let Some(r) = reference {
            if same_data(h, r) {
                out.push(g("heldout_is_reference", format!(
                    "the held-out log `{}` is the reference `{}`: the nominal was fitted on it, so the held-out gap is the regression's own misfit and no effect can show; no effect is named",
                    h.source, r.source
                )));
            }
        }
    }
    if let Some(r) = reference {
        if same_data(log, r) {
            out.push(g("training_is_reference", format!(
                "the training log `{}` is the reference `{}`: the nominal was fitted on this very data, so nothing can differ from it and nothing can be found; no effect is named",
                log.source, r.source
            )));
        }
    }
    out
}

/// Fit gates: the nominal on training, held-out against training, the
/// torque scale, and the count of implausible fits.
pub fn fit_gates(
    train: &[&Segment],
    fit_train: &[Option<f64>; NCH],
    fit_held: &[Option<f64>; NCH],
    nominal: &Nominal,
    not_ranked: &[NotRanked],
    unit: &dyn Fn(usize) -> &'static str,
) -> Vec<Gate> {
    let mut out = Vec::new();
    for c in 0..NCH {
        let (Some(ft), Some(fh)) = (fit_train[c], fit_held[c]) else {
            continue;
        };
        if ft < NOMINAL_FIT_MIN_PCT[c] {
            out.push(Gate {
                kind: "nominal_poor_fit".into(),
                channel: Some(CHANNELS[c].into()),
                message: format!(
                    "the nominal explains the {} channel ({}) poorly on the training data: Fit {ft:.1} % (gate {:.0} %){}; findings in this channel are relative to a poor baseline",
                    CHANNELS[c],
                    unit(c),
                    NOMINAL_FIT_MIN_PCT[c],
                    if ft < 0.0 { ", worse than the signal's mean — a large gap, which a wrong rig file and a large unmeasured force both leave: the verdict weighs a re-fit of the nominal's parameters against a disturbance" } else { "" }
                ),
                figure: ft,
            });
        }
        if ft - fh > HELDOUT_DROP_POINTS {
            out.push(Gate {
                kind: "heldout_drop".into(),
                channel: Some(CHANNELS[c].into()),
                message: format!(
                    "held-out Fit of the {} channel is {:.1} points below training ({ft:.1} → {fh:.1} %): the held-out run holds something the training run does not (another load or rig state, or events); a library effect fitted on training cannot explain it",
                    CHANNELS[c],
                    ft - fh
                ),
                figure: ft - fh,
            });
        }
    }
    if let Nominal::Physics(p) = nominal {
        if let Some(g) = back_emf_gate(train, p) {
            out.push(g);
        }
        // K_t i = y, nominal torque = y − r: least-squares scale, weighted.
        let (mut ym, mut mm) = (0.0, 0.0);
        for s in train {
            if let (Some(y), Some(r)) = (&s.y[TORQUE], &s.r[TORQUE]) {
                for i in 0..y.len() {
                    let w2 = s.weight(TORQUE, i).powi(2);
                    let m = y[i] - r[i];
                    ym += w2 * y[i] * m;
                    mm += w2 * m * m;
                }
            }
        }
        if mm > 0.0 {
            let a = ym / mm;
            if (a - 1.0).abs() > TORQUE_SCALE_TOLERANCE {
                out.push(Gate {
                    kind: "physics_mismatch".into(),
                    channel: Some("torque".into()),
                    message: format!(
                        "the logged torque (K_t i_q) is {a:.2} × what the rig's physics needs for the logged motion and load (tolerance ±{:.0} %): the rig file's torque constant, lead, inertia or mass do not match this log",
                        100.0 * TORQUE_SCALE_TOLERANCE
                    ),
                    figure: a,
                });
            }
        }
    }
    let implausible: Vec<String> = not_ranked
        .iter()
        .filter(|n| n.status == "implausible")
        .map(|n| format!("{} ({})", n.effect, n.reason))
        .collect();
    if implausible.len() >= IMPLAUSIBLE_FITS_MISMATCH {
        out.push(Gate {
            kind: "implausible_fits".into(),
            channel: None,
            message: format!(
                "{} library effects fit physically implausible parameters — the log does not match the rig's physics as described: {}",
                implausible.len(),
                implausible.join("; ")
            ),
            figure: implausible.len() as f64,
        });
    }
    out
}

/// The back-EMF scale `k` in
/// `u_q − R i_q − L_q di_q/dt ≈ k · p ω ψ_f + d · tanh(i_q / 0.1 A)`
/// (least squares over the segments; `None` without a voltage channel or
/// motion). The voltage residual is
/// `u_q − (R i_q + L_q di_q/dt + p ω ψ_f)`, so `r + p ω ψ_f` is the
/// logged back-EMF. The inverter's dead-time voltage `d` (the library's
/// `dead_time` regressor) is fitted alongside: it follows the sign of the
/// current, which follows the motion; left out, it pushed `k` past the
/// tolerance on a closed-world dead-time rig (suite seed 0).
pub fn back_emf_scale(segs: &[&Segment], p: &super::residual::Physics) -> Option<f64> {
    // Normal equations of [e, h] → [k, d].
    let (mut ee, mut eh, mut hh, mut ze, mut zh) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for s in segs {
        let Some(r) = &s.r[VOLTAGE] else { continue };
        for ((ri, w), i) in r.iter().zip(&s.omega).zip(&s.iq) {
            let e = p.pole_pairs * w * p.flux_wb;
            let h = (i / 0.1).tanh();
            let z = ri + e;
            ee += e * e;
            eh += e * h;
            hh += h * h;
            ze += z * e;
            zh += z * h;
        }
    }
    let det = ee * hh - eh * eh;
    if ee <= 0.0 {
        return None;
    }
    // Without current (hh = 0) or collinear: the back-EMF alone.
    Some(if det > 1e-9 * ee * hh.max(1e-300) && hh > 0.0 {
        (ze * hh - zh * eh) / det
    } else {
        ze / ee
    })
}

/// `physics_mismatch` on the voltage channel: the back-EMF scale outside
/// `1 ± BACK_EMF_TOLERANCE`.
fn back_emf_gate(train: &[&Segment], p: &super::residual::Physics) -> Option<Gate> {
    let k = back_emf_scale(train, p)?;
    ((k - 1.0).abs() > BACK_EMF_TOLERANCE).then(|| Gate {
        kind: "physics_mismatch".into(),
        channel: Some("voltage".into()),
        message: format!(
            "the logged back-EMF (u_q − R i_q − L_q di_q/dt) is {k:.2} × the rig file's p ω ψ_f (tolerance ±{:.0} %; magnets lose ≤ 12 % over a 100 K warm-up): the rig file's flux linkage ({:.4} Wb), and with it its torque constant, is not this motor's",
            100.0 * BACK_EMF_TOLERANCE,
            p.flux_wb
        ),
        figure: k,
    })
}
