//! `drive stream FILE.csv`: the CSV read and checked, the drive's state
//! checked, the points sent, the tracking figures printed and written.

use super::access::fetch_params;
use super::client::Client;
use super::{stream, view};
use anyhow::{bail, Context, Result};
use servo_core::ControlParams;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

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
    // Ctrl-C ends the stream with a stop (the drive holds) and the report
    // below; a second Ctrl-C ends the tool at once (exit 1; the drive then
    // finds the stream lost and stops the rod itself).
    let interrupt = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register_conditional_shutdown(signal_hook::consts::SIGINT, 1, Arc::clone(&interrupt)).context("installing the Ctrl-C handler")?;
    let handler = signal_hook::flag::register(signal_hook::consts::SIGINT, Arc::clone(&interrupt)).context("installing the Ctrl-C handler")?;
    let sent = stream::send_until(c, &rows, !asap, true, &interrupt);
    signal_hook::low_level::unregister(handler);
    let r = sent?;
    for g in r.grouped() {
        eprintln!("{name}: {g}");
    }
    if let Some(row) = r.interrupted_at_row {
        eprintln!("{name}: interrupted (Ctrl-C) before row {row}; the stream was ended with `cmd stop`: the drive holds where the reference came to rest");
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
        "interrupted_at_row": r.interrupted_at_row,
        "tracking_rms_um": r.tracking_rms_um,
        "tracking_max_um": r.tracking_max_um,
        "telemetry_records": r.telemetry_records,
        "faults": r.faults,
    });
    std::fs::write(&summary, serde_json::to_string_pretty(&json)?)?;
    println!("figures → {}", summary.display());
    if let Some(row) = r.interrupted_at_row {
        bail!("{name}: interrupted (Ctrl-C) before row {row} of {}: {} points sent; the drive holds", r.rows, r.sent);
    }
    if !r.faults.is_empty() {
        bail!("{}", stream::fault_advice(&name, &r.faults));
    }
    if let Some(first) = r.grouped().first() {
        bail!("{name}: {} points refused or bounded (first: {first})", r.refusals.len());
    }
    Ok(())
}
