//! The screw's true lead from the drive's own logs, for the drive's lead
//! parameter. A lead off by ε makes every drive metre off by ε: the rod
//! stands at `(1 + ε)·x` when the drive believes `x`, a scale error that
//! grows along the stroke (a C7 screw allows 52 µm over 300 mm). Told its
//! true lead the drive's trajectory, limits and telemetry are in the rod's
//! metres, and the observer is left the structure's deflection alone.
//!
//! The linear scale reads `terminal − motor = ε·x + deflection`. At rest the
//! deflection is the axial force through a compliance that grows with the
//! stroke (the screw between the nut and its fixed bearing lengthens), plus
//! what the last move's friction left wound in. So, over the samples at
//! rest, a least-squares fit of
//!
//! `terminal − motor = a_file + ε·x + c·F·x + g·d + h·d·F`
//!
//! with `d` the direction of the last move and `a_file` one offset per log
//! (a scale's zero is wherever it was homed) separates the scale error from
//! the load's: logs at two or more payloads give the slope at zero force.

use super::from_logs::{log_files, read_log, LogSummary};
use anyhow::{bail, Context, Result};
use nalgebra::{DMatrix, DVector};
use std::path::PathBuf;

/// A lead error beyond this (0.1 %, 5 µm per 5 mm turn; twenty times a C7
/// screw's grade) is not a lead: a scale mounted askew, or in other units.
pub const SCALE_ERROR_MAX: f64 = 1.0e-3;
/// Motor speed under which a sample counts as at rest (rad/s; 1.6 mm/s at
/// a 5 mm lead, above the encoder speed's noise at a hold).
const REST_SPEED_RAD_S: f64 = 2.0;
/// How long the motor must have been at rest before its samples count (s):
/// the rod's axial mode (≈ 29 Hz) has rung down by then.
const REST_SETTLE_S: f64 = 0.15;
/// Payloads must differ by this much in force at rest for the fit to tell
/// the load's deflection from the scale error (N).
const FORCE_SPREAD_MIN_N: f64 = 200.0;
/// The rest positions must span this much of the stroke (m).
const TRAVEL_SPREAD_MIN_M: f64 = 0.1;

#[derive(Clone, Debug, serde::Serialize)]
pub struct LeadFit {
    /// ε: the rod travels `(1 + ε)` times what the drive believes.
    pub scale_error: f64,
    /// Its standard error from the fit's residual.
    pub scale_error_sigma: f64,
    /// The lead the drive should be told (m/turn).
    pub lead_m: f64,
    pub samples_at_rest: usize,
    pub residual_rms_m: f64,
    /// Mean force at rest of each log (N).
    pub force_at_rest_n: Vec<f64>,
}

/// Fits the scale error on `logs` (telemetry CSVs as `dataset-from-logs`
/// reads them) recorded by a drive that believed `lead_m`.
pub fn fit(logs: &[PathBuf], lead_m: f64) -> Result<LeadFit> {
    let logs = &log_files(logs)?;
    let mut summary = LogSummary::default();
    // Per sample: file, x, F, d, terminal − motor.
    let mut samples: Vec<(usize, f64, f64, f64, f64)> = Vec::new();
    let mut force_at_rest = Vec::new();
    for (k, path) in logs.iter().enumerate() {
        let (rows, _) = read_log(path, &mut summary)?;
        let mut moving_at = f64::NEG_INFINITY;
        let mut held = 0.0;
        let mut sum_f = (0.0, 0usize);
        for r in &rows {
            if r.speed_rad_s.abs() >= REST_SPEED_RAD_S {
                moving_at = r.t;
                held = r.speed_rad_s.signum();
            }
            let d = r.travel.unwrap_or(held);
            // Before the first move nothing is wound either way.
            if r.t - moving_at < REST_SETTLE_S || d == 0.0 {
                continue;
            }
            samples.push((k, r.motor_m, r.force_n, d, r.terminal_m - r.motor_m));
            sum_f = (sum_f.0 + r.force_n, sum_f.1 + 1);
        }
        if sum_f.1 == 0 {
            bail!("{}: no sample at rest after a move (the motor below {REST_SPEED_RAD_S} rad/s for {REST_SETTLE_S} s): log moves with a dwell after each", path.display());
        }
        force_at_rest.push(sum_f.0 / sum_f.1 as f64);
    }
    let spread = |v: &mut dyn Iterator<Item = f64>| {
        let (lo, hi) = v.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(x), hi.max(x)));
        hi - lo
    };
    let df = spread(&mut force_at_rest.iter().copied());
    if df < FORCE_SPREAD_MIN_N {
        bail!("the logs' forces at rest span {df:.0} N, under {FORCE_SPREAD_MIN_N} N: log at a light and a heavy payload, or the load's deflection cannot be told from the lead");
    }
    let dx = spread(&mut samples.iter().map(|s| s.1));
    if dx < TRAVEL_SPREAD_MIN_M {
        bail!("the rest positions span {:.0} mm, under {:.0} mm: stop at several points along the stroke", dx * 1e3, TRAVEL_SPREAD_MIN_M * 1e3);
    }
    let files = logs.len();
    let cols = files + 4;
    let mut a = DMatrix::<f64>::zeros(samples.len(), cols);
    let mut b = DVector::<f64>::zeros(samples.len());
    for (i, &(k, x, f, d, e)) in samples.iter().enumerate() {
        a[(i, k)] = 1.0;
        a[(i, files)] = x;
        a[(i, files + 1)] = f * x;
        a[(i, files + 2)] = d;
        a[(i, files + 3)] = d * f;
        b[i] = e;
    }
    // Columns scaled to unit RMS, so the SVD's tolerance means the same
    // for metres and newton-metres.
    let scale: Vec<f64> = (0..cols).map(|j| (a.column(j).norm_squared() / samples.len() as f64).sqrt().max(1e-12)).collect();
    for (j, s) in scale.iter().enumerate() {
        a.column_mut(j).scale_mut(1.0 / s);
    }
    let svd = a.clone().svd(true, true);
    let smax = svd.singular_values.max();
    if svd.singular_values.min() < 1e-9 * smax {
        bail!("the logs do not separate the lead from the load's deflection (a degenerate fit): log strokes with stops along the travel at two payloads");
    }
    let sol = svd.solve(&b, 1e-12).map_err(|e| anyhow::anyhow!("lead fit: {e}"))?;
    let resid = &b - &a * &sol;
    let dof = samples.len().saturating_sub(cols).max(1) as f64;
    let s2 = resid.norm_squared() / dof;
    let ata_inv = (a.transpose() * &a).try_inverse().ok_or_else(|| anyhow::anyhow!("lead fit: singular normal matrix"))?;
    let eps = sol[files] / scale[files];
    let sigma = (s2 * ata_inv[(files, files)]).sqrt() / scale[files];
    if !(eps.abs() <= SCALE_ERROR_MAX) {
        bail!(
            "the logs show a scale error of {:.0} µm per 300 mm, beyond the {:.0} µm a lead can be off: check the linear scale's mounting and units",
            eps * 0.3e6,
            SCALE_ERROR_MAX * 0.3e6
        );
    }
    Ok(LeadFit {
        scale_error: eps,
        scale_error_sigma: sigma,
        lead_m: lead_m * (1.0 + eps),
        samples_at_rest: samples.len(),
        residual_rms_m: (resid.norm_squared() / samples.len() as f64).sqrt(),
        force_at_rest_n: force_at_rest,
    })
}

/// `host-sim lead-from-logs`.
#[derive(clap::Args, Debug)]
pub struct LeadArgs {
    /// Telemetry logs (CSV) or folders of them, at two payloads or more,
    /// strokes with stops along the travel (docs/observer-retraining.md).
    #[arg(required = true)]
    pub logs: Vec<PathBuf>,
    /// Output folder for summary.json.
    #[arg(long)]
    pub out: PathBuf,
    /// Rig file, for the lead the drive believed while logging; default:
    /// the shipped rig.
    #[arg(long)]
    pub params: Option<PathBuf>,
}

/// Fits, writes `summary.json`, prints the `drive param set` to apply.
pub fn run_cli(a: &LeadArgs) -> Result<LeadFit> {
    let rig = crate::config::RigConfig::load_or_nominal(a.params.as_ref())?;
    let f = fit(&a.logs, f64::from(rig.control.drive_train.screw_lead_m))?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let summary = serde_json::json!({ "command": "host-sim lead-from-logs", "fit": f, "param_set": { "drive_train.screw_lead_m": f.lead_m } });
    let path = a.out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)?).with_context(|| format!("writing {}", path.display()))?;
    println!(
        "scale error {:+.1} ± {:.1} µm per 300 mm over {} samples at rest (residual {:.1} µm); forces at rest {:?} N",
        f.scale_error * 0.3e6,
        f.scale_error_sigma * 0.3e6,
        f.samples_at_rest,
        f.residual_rms_m * 1e6,
        f.force_at_rest_n.iter().map(|x| x.round()).collect::<Vec<_>>()
    );
    println!("apply with the bridge off: host-sim drive --port PORT param set drive_train.screw_lead_m {:.9}", f.lead_m);
    println!("wrote {}", path.display());
    Ok(f)
}
