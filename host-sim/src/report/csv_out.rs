//! CSV traces. `telemetry.csv` has exactly the fields of the firmware's
//! defmt telemetry record (serialised from the same struct); `plant.csv` has
//! the simulator's truth at the same instants, row for row.

use crate::scenario::RunTrace;
use anyhow::{Context, Result};
use std::path::Path;

pub fn write_trace(trace: &RunTrace, dir: &Path) -> Result<()> {
    let tel_path = dir.join("telemetry.csv");
    let mut w = csv::Writer::from_path(&tel_path).with_context(|| format!("creating {}", tel_path.display()))?;
    for t in &trace.telemetry {
        w.serialize(t).with_context(|| format!("writing {}", tel_path.display()))?;
    }
    w.flush()?;

    let truth_path = dir.join("plant.csv");
    let mut w = csv::Writer::from_path(&truth_path).with_context(|| format!("creating {}", truth_path.display()))?;
    for x in &trace.truth {
        w.serialize(x).with_context(|| format!("writing {}", truth_path.display()))?;
    }
    w.flush()?;
    Ok(())
}
