//! Comparison runs of `host-sim train`: the baselines (random
//! initialisation, IBAS alone, physics least squares) and the paper's
//! Table 2 (opposite and mixed splits, length and error models). They
//! retrain on the same data; the chosen model does not depend on them.

use super::dataset::{Dataset, Direction, ModelKind, SplitSpec};
use super::{train_dataset, TrainOptions, TrainReport};
use anyhow::Result;
use serde::Serialize;

/// The baselines on the chosen model's split and size.
pub(super) fn baselines(ds: &Dataset, opts: &TrainOptions, chosen: &TrainReport) -> Result<std::collections::BTreeMap<String, f64>> {
    let mut out = std::collections::BTreeMap::new();
    let mut base = opts.clone();
    base.hidden = vec![chosen.hidden];
    base.progress = false;
    let mut bp_random = base.clone();
    bp_random.ibas = None;
    if bp_random.optimiser.is_some() {
        out.insert("bp_random_init".to_string(), train_dataset(ds, &bp_random)?.test.rmse_um);
    }
    let mut ibas_only = base.clone();
    ibas_only.optimiser = None;
    if ibas_only.ibas.is_some() {
        out.insert("ibas_only".to_string(), train_dataset(ds, &ibas_only)?.test.rmse_um);
    }
    if let Some(m) = &chosen.test_physics_baseline {
        out.insert("physics_least_squares".to_string(), m.rmse_um);
    }
    Ok(out)
}

/// One row of the paper's Table 2 as this dataset gives it.
#[derive(Clone, Debug, Serialize)]
pub struct Table2Row {
    pub dataset_and_model: String,
    /// Held-out, before compensation (the whole error) and after (residual).
    pub mse_mm2_before: f64,
    pub rmse_mm_before: f64,
    pub mape_before: f64,
    pub mse_mm2_after: f64,
    pub rmse_mm_after: f64,
    pub mape_after: f64,
}

/// {opposite (both ways), mixed} × {length, error}. Opposite rows average
/// the two directions (train on elongation → test contraction, and back).
pub(super) fn table2(ds: &Dataset, opts: &TrainOptions) -> Result<Vec<Table2Row>> {
    let mut rows = Vec::new();
    for kind in [ModelKind::Length, ModelKind::Error] {
        for split_name in ["opposite", "mixed"] {
            let splits: Vec<SplitSpec> = match split_name {
                "opposite" => vec![
                    SplitSpec::Opposite { train: Direction::Elongation },
                    SplitSpec::Opposite { train: Direction::Contraction },
                ],
                _ => vec![opts.split],
            };
            let mut acc = [0.0f64; 6];
            for split in &splits {
                let mut o = opts.clone();
                o.kind = kind;
                o.split = *split;
                o.progress = false;
                let r = train_dataset(ds, &o)?;
                let (b, a) = (&r.test_uncompensated, &r.test);
                for (slot, v) in acc.iter_mut().zip([
                    b.mse_m2 * 1e6,
                    b.rmse_m * 1e3,
                    b.mape_pct.unwrap_or(f64::NAN),
                    a.mse_m2 * 1e6,
                    a.rmse_m * 1e3,
                    a.mape_pct.unwrap_or(f64::NAN),
                ]) {
                    *slot += v / splits.len() as f64;
                }
            }
            rows.push(Table2Row {
                dataset_and_model: format!("{split_name} data, {} model", kind.name()),
                mse_mm2_before: acc[0],
                rmse_mm_before: acc[1],
                mape_before: acc[2],
                mse_mm2_after: acc[3],
                rmse_mm_after: acc[4],
                mape_after: acc[5],
            });
        }
    }
    Ok(rows)
}

pub(super) fn table2_markdown(rows: &[Table2Row]) -> String {
    let mut s = String::from(
        "| dataset and observation model | MSE before (mm²) | RMSE before (mm) | MAPE before (%) | MSE after (mm²) | RMSE after (mm) | MAPE after (%) |\n|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {:.4e} | {:.5} | {:.5} | {:.4e} | {:.5} | {:.5} |\n",
            r.dataset_and_model, r.mse_mm2_before, r.rmse_mm_before, r.mape_before, r.mse_mm2_after, r.rmse_mm_after, r.mape_after
        );
    }
    s
}
