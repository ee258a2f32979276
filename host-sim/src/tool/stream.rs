//! `drive stream FILE.csv`: a setpoint trajectory read, validated and sent.

use super::client::{describe, Client};
use anyhow::{bail, Context, Result};
use servo_core::protocol::{DriveCommand, Reply, Request, StreamPoint};
use std::collections::HashMap;
use std::path::Path;
use std::time::{Duration, Instant};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    pub t_s: f64,
    pub position_m: f64,
    pub velocity_m_s: f64,
    pub force_n: Option<f64>,
}

/// Reads `t_s, position_m, velocity_m_s[, force_n]` (header required, any
/// column order). Every problem is named `file:row:field` (row 1 = the first
/// data row).
pub fn read_csv(path: &Path) -> Result<Vec<Row>> {
    let name = path.display().to_string();
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_path(path).with_context(|| format!("reading {name}"))?;
    let headers: Vec<String> = rdr.headers()?.iter().map(str::to_string).collect();
    let col = |n: &str| headers.iter().position(|h| h == n);
    let need = |n: &str| col(n).with_context(|| format!("{name}: no `{n}` column (need t_s, position_m, velocity_m_s[, force_n])"));
    let (ct, cp, cv, cf) = (need("t_s")?, need("position_m")?, need("velocity_m_s")?, col("force_n"));
    let mut rows = Vec::new();
    let mut errors = Vec::new();
    for (r, rec) in rdr.records().enumerate() {
        let row = r + 1;
        let rec = rec.with_context(|| format!("{name}:{row}"))?;
        let mut field = |c: usize, f: &str| -> Option<f64> {
            let cell = rec.get(c).unwrap_or("");
            match cell.parse::<f64>() {
                Ok(v) if v.is_finite() => Some(v),
                _ => {
                    errors.push(format!("{name}:{row}:{f}: `{cell}` is not a finite number"));
                    None
                }
            }
        };
        let (t, p, v) = (field(ct, "t_s"), field(cp, "position_m"), field(cv, "velocity_m_s"));
        let force = match cf {
            Some(c) if !rec.get(c).unwrap_or("").is_empty() => field(c, "force_n"),
            _ => None,
        };
        if let (Some(t_s), Some(position_m), Some(velocity_m_s)) = (t, p, v) {
            if let Some(prev) = rows.last().map(|x: &Row| x.t_s) {
                if t_s <= prev {
                    errors.push(format!("{name}:{row}:t_s: {t_s} does not increase (previous {prev})"));
                }
            }
            rows.push(Row { t_s, position_m, velocity_m_s, force_n: force });
        }
    }
    if !errors.is_empty() {
        let more = if errors.len() > 20 { format!("\n… and {} more", errors.len() - 20) } else { String::new() };
        bail!("{}{more}", errors.iter().take(20).cloned().collect::<Vec<_>>().join("\n"));
    }
    if rows.is_empty() {
        bail!("{name}: no data rows");
    }
    Ok(rows)
}

#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StreamReport {
    pub rows: usize,
    pub sent: usize,
    pub duration_s: f64,
    pub wall_s: f64,
    /// (row, reason) of every point the drive refused or bounded.
    pub refusals: Vec<(usize, String)>,
    /// The drive stopped taking points (faulted, disabled): sending ended
    /// at this row.
    pub aborted_at_row: Option<usize>,
}

impl StreamReport {
    /// Refusals with consecutive rows of the same reason merged:
    /// `rows 204–400: command refused: NotRunning`.
    pub fn grouped(&self) -> Vec<String> {
        let mut out: Vec<(usize, usize, &str)> = Vec::new();
        for (row, why) in &self.refusals {
            match out.last_mut() {
                Some((_, last, w)) if *w == why.as_str() && *last + 1 == *row => *last = *row,
                _ => out.push((*row, *row, why.as_str())),
            }
        }
        out.into_iter()
            .map(|(a, b, w)| if a == b { format!("row {a}: {w}") } else { format!("rows {a}–{b}: {w}") })
            .collect()
    }
}

/// A refusal after which further points are pointless.
fn stops_stream(r: &Reply) -> bool {
    use servo_core::protocol::Error;
    use servo_core::CommandError as E;
    match r {
        Reply::Error(Error::Command(E::NotRunning | E::Faulted(_) | E::NotHomed)) => true,
        // The core server's wording for the same refusals.
        Reply::Error(Error::Stream { reason }) => {
            ["faults latched", "not running", "not homed", "not commutated"].iter().any(|w| reason.text().contains(w))
        }
        _ => false,
    }
}

/// Sends the rows as stream points. `paced`: at the rows' times on the
/// wall clock; else back to back (a fast-paced simulated drive steps one
/// stream period per frame). Ends with `Stop` (the drive holds).
pub fn send(client: &mut Client, rows: &[Row], paced: bool) -> Result<StreamReport> {
    let t0 = Instant::now();
    let mut seq_row = HashMap::new();
    let mut aborted_at_row = None;
    for (i, r) in rows.iter().enumerate() {
        if let Some(u) = client.unsolicited.iter().find(|u| stops_stream(&u.error)) {
            aborted_at_row = Some(seq_row.get(&u.seq).copied().unwrap_or(i + 1));
            break;
        }
        if paced {
            let due = Duration::from_secs_f64((r.t_s - rows[0].t_s).max(0.0));
            while t0.elapsed() < due {
                client.poll(Duration::ZERO)?;
                let left = due.saturating_sub(t0.elapsed());
                if left > Duration::from_millis(2) {
                    std::thread::sleep(left - Duration::from_millis(1));
                }
            }
        } else if i % 16 == 0 {
            client.poll(Duration::ZERO)?;
        }
        let p = StreamPoint {
            position_m: r.position_m as f32,
            velocity_m_s: r.velocity_m_s as f32,
            force_n: r.force_n.map(|f| f as f32),
        };
        let seq = client.send(Request::Stream(p))?;
        seq_row.insert(seq, i + 1);
    }
    // End the stream, collecting any late refusals on the way.
    let end = client.request(Request::Command(DriveCommand::Stop));
    let mut report = StreamReport {
        rows: rows.len(),
        sent: seq_row.len(),
        aborted_at_row,
        duration_s: rows.last().map_or(0.0, |r| r.t_s) - rows[0].t_s,
        wall_s: t0.elapsed().as_secs_f64(),
        refusals: vec![],
    };
    for u in client.unsolicited.drain(..) {
        let row = seq_row.get(&u.seq).copied().unwrap_or(0);
        let why = match &u.error {
            Reply::Error(e) => describe(e),
            other => format!("{other:?}"),
        };
        report.refusals.push((row, why));
    }
    match end? {
        Reply::Error(e) => report.refusals.push((0, format!("ending the stream: {}", describe(&e)))),
        _ => {}
    }
    Ok(report)
}
