//! Whether two logs can be compared at all (the log against its reference
//! or its held-out log): the same sampling rate, the same units in the
//! columns a nominal is fitted on, and the same signals logged. Refused
//! with the column and the figure.

use super::log::Log;
use anyhow::{bail, Result};

/// Sampling rates (median step) differing by more than this share: the
/// Savitzky–Golay window, the lags of the regression nominal and every
/// time constant fitted on one log would mean another thing on the other.
pub const RATE_TOLERANCE: f64 = 0.01;
/// A column whose typical size (95th percentile of |x|) differs between
/// the logs by more than this factor is in another unit, or is another
/// signal (a force in N where a current in A was logged: ×100…×1000; mm
/// for m: ×1000). Runs of one rig at other loads or speeds differ by a
/// few times, not by this.
pub const SCALE_FACTOR_MAX: f64 = 20.0;
/// The columns compared by scale: those whose unit the nominal relies on
/// and that are never near zero on a moving rig.
pub const SCALE_COLUMNS: [&str; 6] = [
    "current_q_a",
    "current_a_a",
    "current_b_a",
    "position_reference_m",
    "terminal_position_m",
    "voltage_q_v",
];

/// Signals that change what the nominal predicts or which channels exist:
/// logged in one log and not in the other, a nominal fitted on one is
/// applied to inputs it never saw (a load the reference's regression has
/// no coefficient for) or a channel is scored that was never trained.
pub const SHARED_SIGNALS: [(&str, &[&str]); 7] = [
    ("position_reference_m", &["position_reference_m"]),
    ("terminal_position_m", &["terminal_position_m"]),
    ("motor_angle_rad", &["motor_angle_rad"]),
    // The drive's q current, or the phase currents it is computed from.
    ("current_q_a", &["current_q_a", "current_a_a"]),
    ("voltage_q_v", &["voltage_q_v"]),
    ("load_force_n", &["load_force_n"]),
    ("tilt_deg", &["tilt_deg"]),
];

fn median_step(log: &Log) -> Option<f64> {
    let t = log.get("time_s")?;
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).filter(|d| *d > 0.0).collect();
    if d.is_empty() {
        return None;
    }
    d.sort_by(f64::total_cmp);
    Some(d[d.len() / 2])
}

fn p95_abs(x: &[f64]) -> f64 {
    let mut a: Vec<f64> = x.iter().map(|v| v.abs()).filter(|v| v.is_finite()).collect();
    if a.is_empty() {
        return 0.0;
    }
    a.sort_by(f64::total_cmp);
    a[(a.len() * 95 / 100).min(a.len() - 1)]
}

/// Refuses `other` (`role`: "reference", "held-out log") against `log`
/// when the sampling rates differ by more than `RATE_TOLERANCE` or a
/// column of `SCALE_COLUMNS` differs in size by more than
/// `SCALE_FACTOR_MAX`.
pub fn comparable(log: &Log, other: &Log, role: &str) -> Result<()> {
    let mut errors = Vec::new();
    if let (Some(a), Some(b)) = (median_step(log), median_step(other)) {
        let rel = (a - b).abs() / a.min(b);
        if rel > RATE_TOLERANCE {
            errors.push(format!(
                "column `time_s`: sampled at {:.4} Hz in `{}` and {:.4} Hz in the {role} `{}` (median step {a:.6} s vs {b:.6} s, {:.1} % apart; at most {:.0} %): resample one to the other's rate",
                1.0 / a,
                log.source,
                1.0 / b,
                other.source,
                100.0 * rel,
                100.0 * RATE_TOLERANCE
            ));
        }
    }
    for (signal, columns) in SHARED_SIGNALS {
        let has = |l: &Log| columns.iter().any(|c| l.has(c));
        let (a, b) = (has(log), has(other));
        if a != b {
            let (with, without) = if a { (&log.source, format!("the {role} `{}`", other.source)) } else { (&other.source, format!("`{}`", log.source)) };
            errors.push(format!(
                "column `{signal}`: logged in `{with}` but not in {without}: a nominal fitted on one log would be applied to a signal it never saw, or a channel scored that was never trained; log it in both, or remove it from both"
            ));
        }
    }
    for c in SCALE_COLUMNS {
        let (Some(x), Some(y)) = (log.get(c), other.get(c)) else {
            continue;
        };
        let (sx, sy) = (p95_abs(x), p95_abs(y));
        if sx <= 0.0 || sy <= 0.0 {
            continue;
        }
        let f = sx.max(sy) / sx.min(sy);
        if f > SCALE_FACTOR_MAX {
            errors.push(format!(
                "column `{c}`: typical size (95th percentile of |x|) {sx:.4e} in `{}` against {sy:.4e} in the {role} `{}`, ×{f:.0} apart (at most ×{SCALE_FACTOR_MAX:.0}): one of them holds another unit or another signal (a force where a current is expected, mm for m)",
                log.source,
                other.source
            ));
        }
    }
    if !errors.is_empty() {
        bail!(
            "`{}` and the {role} `{}` cannot be compared:\n  {}",
            log.source,
            other.source,
            errors.join("\n  ")
        );
    }
    Ok(())
}
