//! `drive stream FILE.csv`: the CSV read and checked, the drive's state
//! checked, the points sent, the tracking figures printed and written.

use super::access::fetch_params;
use super::client::Client;
use super::{stream, view};
use anyhow::{bail, Context, Result};
use servo_core::ControlParams;
use std::path::Path;

pub fn run(c: &mut Client, file: &Path, asap: bool, out: &Path) -> Result<()> {
    let rows = stream::read_csv(file)?;
    let p = fetch_params(c, &ControlParams::default())?;
    let period = c.info.as_ref().map_or(0.0, |i| i.stream_period_s);
    let name = file.display().to_string();
    // A drive that would refuse every point is named before anything is
    // sent, with the command that gets it running.
    let st = view::status(c)?;
    if st.faults != 0 || st.mode != servo_core::Mode::Running {
        let faults = if st.faults != 0 { format!(", faults latched: {}", view::fault_names(st.faults).join(", ")) } else { String::new() };
        bail!("{name}: the drive is {:?}{faults}, not Running: nothing was sent; next: {}", st.mode, view::next_step(&st));
    }
    let mut limits = stream::StreamLimits::of(&p, period);
    limits.start_reference_m = Some(stream::reference_position(c)?);
    stream::check_rows(&name, &rows, &limits)?;
    let r = stream::send_with(c, &rows, !asap, true)?;
    for g in r.grouped() {
        eprintln!("{name}: {g}");
    }
    if let Some(row) = r.aborted_at_row {
        eprintln!("{name}: the drive stopped taking points at row {row}; sending ended there");
    }
    let fig = |x: Option<f64>| x.map_or("–".to_string(), |v| format!("{v:.1}"));
    println!(
        "{} of {} points sent over {:.3} s ({:.3} s wall), {} refused or bounded; following error RMS {} µm, max {} µm ({} records)",
        r.sent,
        r.rows,
        r.duration_s,
        r.wall_s,
        r.refusals.len(),
        fig(r.tracking_rms_um),
        fig(r.tracking_max_um),
        r.telemetry_records
    );
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let summary = out.join("summary.json");
    let json = serde_json::json!({
        "file": name,
        "rows": r.rows,
        "sent": r.sent,
        "duration_s": r.duration_s,
        "wall_s": r.wall_s,
        "refusals": r.refusals.len(),
        "refusal_runs": r.grouped(),
        "aborted_at_row": r.aborted_at_row,
        "tracking_rms_um": r.tracking_rms_um,
        "tracking_max_um": r.tracking_max_um,
        "telemetry_records": r.telemetry_records,
        "faults": r.faults,
    });
    std::fs::write(&summary, serde_json::to_string_pretty(&json)?)?;
    println!("figures → {}", summary.display());
    if !r.faults.is_empty() {
        bail!("{}", stream::fault_advice(&name, &r.faults));
    }
    if let Some(first) = r.grouped().first() {
        bail!("{name}: {} points refused or bounded (first: {first})", r.refusals.len());
    }
    Ok(())
}
