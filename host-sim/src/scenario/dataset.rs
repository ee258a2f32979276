//! Observer datasets: the paper's elongation/contraction cycle run
//! closed-loop at several tilt swings, stroke tops and payloads, on the
//! rig file's rig and on rigs drawn within a second unit's tolerances
//! (stiffness, friction, lead), each with its friction identified into the
//! drive's feedforward as the bench workflow does; every sample holds what
//! the firmware itself has (encoder speed, nut speed and displacement through
//! the lead, load force from i_q or the load cell) and, as the target, what
//! the test rig's grating scale adds (terminal error and terminal length).
//!
//! Each leg of each cycle is one run: splits are by run, never by sample.
//! No cycle is the paper's run (top 0.45 m with a 30° tilt swing): that
//! run evaluates the observer, so it is held out by trajectory.

use super::stroke_cycle::{run_stroke_cycle, Direction, StrokeCycle};
use crate::config::RigConfig;
use crate::rigs::{Draw, FamilySpec, C7_LEAD_ERROR_M_PER_M};
use crate::trainer::dataset::{force_column, ForceSource, ALL_COLUMNS};
use anyhow::{bail, Context, Result};
use rand::SeedableRng;
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;

/// Table 3 of the paper: the leg's length with the rod retracted. Terminal
/// length = this + terminal position, which keeps MAPE on length finite.
pub const LEG_BASE_LENGTH_M: f64 = 0.60;

/// One dataset row; the column names are the trainer's contract.
#[derive(Clone, Debug, Serialize)]
pub struct DatasetRow {
    pub run_id: u32,
    pub direction: Direction,
    pub tilt_swing_deg: f64,
    pub payload_scale: f64,
    pub time_s: f64,
    pub motor_speed_rad_s: f64,
    pub nut_speed_m_s: f64,
    pub nut_displacement_m: f64,
    pub load_force_n: f64,
    pub terminal_length_m: f64,
    pub motor_side_position_m: f64,
    pub terminal_error_m: f64,
}

/// Which cycles make up a dataset.
#[derive(Clone, Debug)]
pub struct DatasetSpec {
    pub tilt_swings_deg: Vec<f64>,
    pub payload_scales: Vec<f64>,
    /// Where each elongation turns round (m); cycle `k` of a rig uses top
    /// `k mod len`.
    pub tops_m: Vec<f64>,
    /// Rigs drawn within [`family_spec`] besides the rig file's own.
    pub family_rigs: usize,
    /// Each rig's friction identified into its feedforward first (else
    /// the rig file's `[control]` as it is).
    pub identify_friction: bool,
    pub seed: u64,
}

impl Default for DatasetSpec {
    /// 3 tilt swings × 6 payloads on the rig file's rig and 16 drawn rigs:
    /// 306 cycles, 612 runs. Swings up to 40° around the paper's 30° but
    /// not it, tops either side of its 0.45 m, payloads from 2 % (the
    /// platform's lightest leg) to rated.
    fn default() -> Self {
        Self {
            tilt_swings_deg: vec![10.0, 20.0, 40.0],
            payload_scales: vec![0.02, 0.1, 0.25, 0.5, 0.75, 1.0],
            tops_m: vec![0.40, 0.44, 0.47, 0.49],
            family_rigs: 16,
            identify_friction: true,
            seed: 11,
        }
    }
}

/// The paper's run, which evaluates the observer: no training cycle may be it.
pub fn is_paper_trajectory(top_m: f64, tilt_swing_deg: f64) -> bool {
    let p = StrokeCycle::paper(0);
    (top_m - p.top_m).abs() < 1e-9 && (tilt_swing_deg - p.tilt_swing_deg).abs() < 1e-9
}

/// The spread the shipped weights are trained over: a second unit's
/// structure stiffness ±15 %, friction ±30 %, lead within a C7 screw's
/// grade; nothing else departs from the rig file (payload is the spec's
/// `payload_scales`).
pub fn family_spec() -> FamilySpec {
    FamilySpec {
        stiffness_tol: 0.15,
        friction_tol: 0.30,
        payload_min: 1.0,
        payload_max: 1.0,
        inertia_tol: 0.0,
        resistance_min: 1.0,
        resistance_max: 1.0,
        inductance_tol: 0.0,
        flux_min: 1.0,
        flux_max: 1.0,
        lead_error_max: C7_LEAD_ERROR_M_PER_M,
    }
}

/// The rig file's rig (no departure), then `spec.family_rigs` draws from
/// [`family_spec`] (encoder zero left at the file's), named.
pub fn family_draws(spec: &DatasetSpec) -> Vec<(String, Draw)> {
    let fs = family_spec();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(spec.seed);
    let mut draws = vec![("rig file".to_string(), Draw::BASE)];
    let mut previous = Draw::BASE;
    for k in 0..spec.family_rigs {
        // Draws come in mirrored pairs (every departure reversed), so the
        // family's mean is the rig file's: an odd lead error or stiffness
        // left over by chance would bias the map on the nominal rig.
        let d = if k % 2 == 0 {
            Draw { encoder_zero_rad: 0.0, ..Draw::random(&fs, &mut rng) }
        } else {
            let m = |f: f64| 2.0 - f;
            Draw {
                stiffness: m(previous.stiffness),
                coulomb: m(previous.coulomb),
                viscous: m(previous.viscous),
                screw_mu: m(previous.screw_mu),
                lead_error_m_per_m: -previous.lead_error_m_per_m,
                ..previous
            }
        };
        previous = d;
        let name = format!(
            "drawn rig {k}: stiffness ×{:.3}, friction ×{:.2}/{:.2}/{:.2}, lead {:+.1} µm/300 mm",
            d.stiffness,
            d.coulomb,
            d.viscous,
            d.screw_mu,
            d.lead_error_m_per_m * 0.3e6
        );
        draws.push((name, d));
    }
    draws
}

/// The rigs of a dataset ([`family_draws`]), each with the friction
/// `tune identify` finds written into its feedforward (when the spec asks).
pub fn dataset_rigs(rig: &RigConfig, spec: &DatasetSpec) -> Result<Vec<(String, RigConfig)>> {
    let draws = family_draws(spec);
    draws
        .into_par_iter()
        .enumerate()
        .map(|(i, (name, d))| {
            let drawn = d.apply(rig);
            if !spec.identify_friction {
                return Ok((name, drawn));
            }
            let (tuned, _) = crate::tuning::identify_friction_sim(&drawn, spec.seed.wrapping_mul(100).wrapping_add(i as u64))
                .with_context(|| format!("{name}: identifying its friction"))?;
            Ok((name, tuned))
        })
        .collect()
}

/// Runs every cycle of `spec` on every rig of [`dataset_rigs`] and returns
/// the rows of the moving legs.
pub fn generate(rig: &RigConfig, spec: &DatasetSpec) -> Result<Vec<DatasetRow>> {
    if !rig.plant.sensors.linear_scale_enabled {
        bail!("the rig has no linear scale ([plant.sensors] linear_scale_enabled = false): no target to learn");
    }
    if spec.tops_m.is_empty() {
        bail!("no stroke top given");
    }
    let rigs = dataset_rigs(rig, spec)?;
    let per_rig: Vec<Vec<DatasetRow>> = rigs.par_iter().enumerate().map(|(r, (name, rig))| generate_on(rig, spec, r).with_context(|| name.clone())).collect::<Result<_>>()?;
    let mut rows = Vec::new();
    let mut run_id = 0u32;
    for block in per_rig {
        let mut last = None;
        for mut row in block {
            if last != Some(row.run_id) {
                last = Some(row.run_id);
                run_id += 1;
            }
            row.run_id = run_id - 1;
            rows.push(row);
        }
    }
    Ok(rows)
}

/// The cycles of `spec` on one rig (`r`: its index, for the seeds); run
/// ids local to the rig.
fn generate_on(rig: &RigConfig, spec: &DatasetSpec, r: usize) -> Result<Vec<DatasetRow>> {
    let lead = f64::from(rig.control.drive_train.screw_lead_m);
    let mut rows = Vec::new();
    let mut run_id = 0u32;
    let mut k = 0usize;
    for (i, &swing) in spec.tilt_swings_deg.iter().enumerate() {
        for (j, &payload) in spec.payload_scales.iter().enumerate() {
            let top_m = spec.tops_m[k % spec.tops_m.len()];
            k += 1;
            if is_paper_trajectory(top_m, swing) {
                bail!("cycle tilt ±{swing}°, top {top_m} m is the paper's run, which evaluates the observer: choose another swing or top");
            }
            let cycle = StrokeCycle {
                tilt_swing_deg: swing,
                payload_scale: payload,
                top_m,
                seed: spec.seed.wrapping_mul(1000).wrapping_add((r * 10_000 + i * 100 + j) as u64),
                ..StrokeCycle::paper(0)
            };
            let trace = run_stroke_cycle(rig, &cycle).with_context(|| format!("cycle tilt ±{swing}°, top {top_m} m, payload ×{payload}"))?;
            if let Some(why) = &trace.aborted {
                bail!("cycle tilt ±{swing}°, payload ×{payload} stopped early: {why}");
            }
            for leg in [Direction::Elongation, Direction::Contraction] {
                for (t, x) in trace.telemetry.iter().zip(&trace.truth).filter(|(_, x)| x.direction == leg) {
                    let Some(scale_m) = t.terminal_position_m else {
                        bail!("telemetry at t = {} s has no linear-scale reading", t.time_s);
                    };
                    let speed = f64::from(t.speed_rad_s);
                    let motor_side = f64::from(t.motor_position_m);
                    let scale = f64::from(scale_m);
                    rows.push(DatasetRow {
                        run_id,
                        direction: leg,
                        tilt_swing_deg: swing,
                        payload_scale: payload,
                        time_s: x.time_s,
                        motor_speed_rad_s: speed,
                        nut_speed_m_s: speed * lead / (2.0 * std::f64::consts::PI),
                        nut_displacement_m: motor_side,
                        load_force_n: f64::from(t.load_force_estimate_n),
                        terminal_length_m: LEG_BASE_LENGTH_M + scale,
                        motor_side_position_m: motor_side,
                        terminal_error_m: scale - motor_side,
                    });
                }
                run_id += 1;
            }
        }
    }
    Ok(rows)
}

/// Writes `rows` as CSV, the force column named for `source`, the force
/// the drive's observer read (`trainer::dataset::force_column`).
pub fn write_csv(rows: &[DatasetRow], path: &Path, source: ForceSource) -> Result<()> {
    let mut w = csv::WriterBuilder::new().has_headers(false).from_path(path).with_context(|| format!("creating {}", path.display()))?;
    w.write_record(ALL_COLUMNS.map(|c| if c == "load_force_n" { force_column(source) } else { c }))?;
    for r in rows {
        w.serialize(r).with_context(|| format!("writing {}", path.display()))?;
    }
    w.flush()?;
    Ok(())
}
