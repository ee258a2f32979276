//! What a command leaves behind: `summary.json`, CSV traces, PNG plots.

pub mod csv_out;
pub mod metrics;
pub mod plots;

use anyhow::{Context, Result};
use std::path::Path;

/// Writes any serialisable summary as pretty JSON to `dir/summary.json`.
pub fn write_summary<T: serde::Serialize>(summary: &T, dir: &Path) -> Result<()> {
    let path = dir.join("summary.json");
    let text = serde_json::to_string_pretty(summary)?;
    std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))
}
