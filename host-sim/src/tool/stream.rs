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
    // Flexible: a short or long row is named below, with the others.
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).flexible(true).from_path(path).with_context(|| format!("reading {name}"))?;
    let headers: Vec<String> = rdr.headers().with_context(|| format!("reading {name}"))?.iter().map(str::to_string).collect();
    if headers.iter().all(|h| h.is_empty()) {
        bail!("{name}: empty: no header row (need t_s, position_m, velocity_m_s[, force_n])");
    }
    for (i, h) in headers.iter().enumerate() {
        if headers[..i].contains(h) {
            bail!("{name}: the header names `{h}` twice (columns {} and {}): which one is meant is unknown", headers.iter().position(|x| x == h).unwrap_or(0) + 1, i + 1);
        }
    }
    let col = |n: &str| headers.iter().position(|h| h == n);
    let need = |n: &str| {
        col(n).with_context(|| format!("{name}: no `{n}` column (need t_s, position_m, velocity_m_s[, force_n], in s, m, m/s, N; the header has: {})", headers.join(", ")))
    };
    let (ct, cp, cv, cf) = (need("t_s")?, need("position_m")?, need("velocity_m_s")?, col("force_n"));
    let mut rows = Vec::new();
    let mut errors = Vec::new();
    for (r, rec) in rdr.records().enumerate() {
        let row = r + 1;
        let rec = rec.with_context(|| format!("{name}:{row}"))?;
        if rec.len() != headers.len() {
            errors.push(format!("{name}:{row}: {} fields, the header has {} (a truncated row, or a stray delimiter)", rec.len(), headers.len()));
            continue;
        }
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

/// What the drive takes, for checking a CSV before anything is sent.
#[derive(Clone, Copy, Debug)]
pub struct StreamLimits {
    pub stroke_min_m: f64,
    pub stroke_max_m: f64,
    pub velocity_max_m_s: f64,
    pub force_max_n: f64,
    /// The drive's stream period (s), if it expects one; else any interval
    /// from `interval_min_s` to `interval_max_s`.
    pub period_s: Option<f64>,
    pub interval_min_s: f64,
    pub interval_max_s: f64,
    /// Where the drive's position reference rests, m, when known: the
    /// first point is reached from there (`START_OFFSET_MAX_M`).
    pub start_reference_m: Option<f64>,
}

impl StreamLimits {
    pub fn of(p: &servo_core::ControlParams, period_s: f32) -> Self {
        Self {
            stroke_min_m: f64::from(p.limits.stroke_min_m),
            stroke_max_m: f64::from(p.limits.stroke_max_m),
            velocity_max_m_s: f64::from(p.trajectory.max_velocity_m_s),
            force_max_n: f64::from(p.thrust_peak_n()),
            period_s: (period_s > 0.0).then_some(f64::from(period_s)),
            interval_min_s: f64::from(p.position_period_s()),
            interval_max_s: f64::from(p.stream.period_max_s),
            start_reference_m: None,
        }
    }
}

/// Seconds as milliseconds to 3 decimals, or in exponent form when huge.
fn ms_text(s: f64) -> String {
    let ms = s * 1e3;
    if ms.abs() < 1e6 {
        format!("{ms:.3}")
    } else {
        format!("{ms:.3e}")
    }
}

/// ` (t_s in milliseconds? the column is in seconds)` when a step of `dt`
/// read as milliseconds would lie within `lo … hi` (s).
fn milliseconds_hint(dt: f64, lo: f64, hi: f64) -> &'static str {
    let s = dt * 1e-3;
    if s >= lo * (1.0 - PERIOD_TOLERANCE) && s <= hi * (1.0 + PERIOD_TOLERANCE) {
        " (t_s in milliseconds? the column is in seconds)"
    } else {
        ""
    }
}

/// A row's stated velocity may differ from its position steps by this
/// (m/s) plus `VELOCITY_AGREEMENT_REL` of it: the trapezoid rule's error on
/// a jerk-limited path at 100 Hz is ≈ 2e-4 m/s.
pub const VELOCITY_AGREEMENT_M_S: f64 = 0.01;
pub const VELOCITY_AGREEMENT_REL: f64 = 0.05;
/// A row interval may differ from the drive's stream period by this part.
pub const PERIOD_TOLERANCE: f64 = 0.02;
/// The drive starts a stream from rest where its reference is, and reaches
/// the first point within one slowest interval: a first point that moves
/// or lies away from the reference starts with a lurch. Measured on the
/// shipped rig (fast-paced simulated drive, 0.5 s at the first point's
/// velocity): a 0.079 m/s start gives 596 µm of following error, 0.01 m/s
/// 56 µm, 0.005 m/s 27 µm; a first point 1 mm from the reference gives
/// 1028 µm, 0.5 mm 529 µm, 0.1 mm 156 µm: 1.0–1.6 µm per µm of offset;
/// at 1.6, 10 µm would give 16 µm (not measured). The two bounds below keep the start
/// within the stream's 50 µm following bound together.
pub const START_VELOCITY_MAX_M_S: f64 = 0.005;
pub const START_OFFSET_MAX_M: f64 = 10e-6;
/// Following error per m/s of a start from rest, s (the 0.079 m/s case).
const LURCH_S: f64 = 7.5e-3;

/// The first row against a drive at rest with its reference at
/// `reference_m` (when known): problems named `file:1:field`.
fn check_start(name: &str, first: &Row, reference_m: Option<f64>) -> Vec<String> {
    let mut errors = Vec::new();
    if first.velocity_m_s.abs() > START_VELOCITY_MAX_M_S {
        errors.push(format!(
            "{name}:1:velocity_m_s: the trajectory starts moving at {} m/s, but the drive starts every stream from rest: the rod would lurch to that speed (≈ {:.0} µm of following error); start the trajectory from rest (|velocity| ≤ {} m/s in row 1, accelerating within the file) or add a lead-in from rest",
            first.velocity_m_s,
            first.velocity_m_s.abs() * LURCH_S * 1e6,
            START_VELOCITY_MAX_M_S
        ));
    }
    if let Some(x) = reference_m {
        let off = first.position_m - x;
        if off.abs() > START_OFFSET_MAX_M {
            errors.push(format!(
                "{name}:1:position_m: the trajectory starts at {} m, {:.3} mm from where the drive holds the rod ({x:.6} m): the rod would jump there within one setpoint interval; move there first (`move {}`) or start the trajectory at {x:.6} m (within {:.0} µm)",
                first.position_m,
                off * 1e3,
                first.position_m,
                START_OFFSET_MAX_M * 1e6
            ));
        }
    }
    errors
}

/// Where the drive's position reference rests, m, from telemetry (any
/// telemetry setting is replaced, then off). A reference still moving (a
/// move, or the stop that ends a stream) is waited for up to the client's
/// timeout: it rests when two records 4 ms apart agree.
pub fn reference_position(client: &mut Client) -> Result<f64> {
    use servo_core::protocol::TelemetryField as F;
    client.ask(Request::Telemetry { fields: 1 << F::PositionReference as u32, rate_hz: TRACKING_RATE_HZ })?;
    client.telemetry.clear();
    let t0 = Instant::now();
    let (mut last, mut rest) = (None::<f32>, None::<f32>);
    while rest.is_none() && t0.elapsed() < client.timeout {
        client.poll(Duration::from_millis(5))?;
        for t in client.telemetry.drain(..) {
            let x = t.values.first().copied();
            if x.is_some() && x == last {
                rest = x;
            }
            last = x;
        }
    }
    client.request(Request::Telemetry { fields: 0, rate_hz: 0 })?;
    client.telemetry.clear();
    match (rest, last) {
        (Some(x), _) => Ok(f64::from(x)),
        (None, Some(x)) => bail!(
            "the drive's position reference is still moving (at {x} m after {:.1} s: a move or a stop in progress): wait for it to end (`status`), then try again",
            client.timeout.as_secs_f64()
        ),
        (None, None) => bail!("no telemetry record with the position reference arrived: where the stream would start is unknown"),
    }
}

/// Checks the rows against what the drive takes: stroke, speed, force,
/// the interval between rows against the drive's rate, and each row's
/// velocity against its position step. Every problem names
/// `file:row:field` and the figures.
pub fn check_rows(name: &str, rows: &[Row], l: &StreamLimits) -> Result<()> {
    // A first point outside the stroke is named by the stroke check below;
    // moving there is no fix.
    let reference = l.start_reference_m.filter(|_| rows.first().is_some_and(|r| (l.stroke_min_m..=l.stroke_max_m).contains(&r.position_m)));
    let mut errors = rows.first().map(|r| check_start(name, r, reference)).unwrap_or_default();
    for (i, r) in rows.iter().enumerate() {
        let row = i + 1;
        if r.position_m < l.stroke_min_m || r.position_m > l.stroke_max_m {
            errors.push(format!(
                "{name}:{row}:position_m: {} m outside the stroke {} … {} m (control.limits.stroke_min_m, stroke_max_m){}",
                r.position_m,
                l.stroke_min_m,
                l.stroke_max_m,
                super::moves::millimetre_hint(r.position_m, l.stroke_min_m, l.stroke_max_m)
            ));
        }
        if r.velocity_m_s.abs() > l.velocity_max_m_s {
            let hint = if (r.velocity_m_s / 1000.0).abs() <= l.velocity_max_m_s { " (mm/s? the column is in m/s)" } else { "" };
            errors.push(format!("{name}:{row}:velocity_m_s: {} m/s beyond control.trajectory.max_velocity_m_s = {} m/s{hint}", r.velocity_m_s, l.velocity_max_m_s));
        }
        if let Some(f) = r.force_n {
            if f.abs() > l.force_max_n {
                errors.push(format!("{name}:{row}:force_n: {f} N beyond the motor's peak thrust {:.0} N", l.force_max_n));
            }
        }
        if i == 0 {
            continue;
        }
        let prev = &rows[i - 1];
        let dt = r.t_s - prev.t_s;
        match l.period_s {
            Some(t) if (dt - t).abs() > PERIOD_TOLERANCE * t => errors.push(format!(
                "{name}:{row}:t_s: a step of {} ms; the drive expects one every {:.3} ms (its stream period){}: resample the CSV to {:.0} Hz{}",
                ms_text(dt),
                t * 1e3,
                milliseconds_hint(dt, t, t),
                1.0 / t,
                // Another period is only a fix within what the drive interpolates.
                if dt >= l.interval_min_s && dt <= l.interval_max_s { format!(", or serve the simulated drive with --stream-period-s {dt:.6}") } else { String::new() }
            )),
            None if dt < l.interval_min_s * (1.0 - PERIOD_TOLERANCE) || dt > l.interval_max_s * (1.0 + PERIOD_TOLERANCE) => errors.push(format!(
                "{name}:{row}:t_s: a step of {} ms; the drive takes {:.3} … {:.3} ms (position-loop period … control.stream.period_max_s){}",
                ms_text(dt),
                l.interval_min_s * 1e3,
                l.interval_max_s * 1e3,
                milliseconds_hint(dt, l.interval_min_s, l.interval_max_s)
            )),
            _ => {}
        }
        if dt > 0.0 {
            let step = (r.position_m - prev.position_m) / dt;
            let mean = 0.5 * (r.velocity_m_s + prev.velocity_m_s);
            if (step - mean).abs() > VELOCITY_AGREEMENT_M_S + VELOCITY_AGREEMENT_REL * mean.abs() {
                // The column in mm/s agrees with the steps once read as such.
                let hint = if (step - mean / 1000.0).abs() <= VELOCITY_AGREEMENT_M_S * 1e-3 + VELOCITY_AGREEMENT_REL * (mean / 1000.0).abs() {
                    " (mm/s? the column is in m/s)"
                } else {
                    ""
                };
                errors.push(format!(
                    "{name}:{row}:velocity_m_s: the position step from row {} is {:.4} m/s ({:.3} mm in {:.3} ms), the velocity column says {:.4} m/s (mean of the two rows){hint}",
                    row - 1,
                    step,
                    (r.position_m - prev.position_m) * 1e3,
                    dt * 1e3,
                    mean
                ));
            }
        }
    }
    if !errors.is_empty() {
        let more = if errors.len() > 20 { format!("\n… and {} more", errors.len() - 20) } else { String::new() };
        bail!("{}{more}\nnothing was sent to the drive", errors.iter().take(20).cloned().collect::<Vec<_>>().join("\n"));
    }
    Ok(())
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
    /// The user interrupted (Ctrl-C) before this row was sent: the stream
    /// was ended with `Stop` there.
    pub interrupted_at_row: Option<usize>,
    /// Following error (position reference − motor position) over the
    /// telemetry records received while streaming, µm.
    pub tracking_rms_um: Option<f64>,
    pub tracking_max_um: Option<f64>,
    pub telemetry_records: usize,
    /// The telemetry records behind the tracking figures: (drive time s,
    /// position reference m, motor position m).
    #[serde(skip)]
    pub tracking_trace: Vec<[f64; 3]>,
    /// Faults latched at the end of the stream, by name.
    pub faults: Vec<String>,
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

/// Telemetry rate for the tracking figures (fits a 115 200 Bd link).
pub const TRACKING_RATE_HZ: u16 = 250;

/// A refusal after which further points are pointless.
fn stops_stream(r: &Reply) -> bool {
    use servo_core::protocol::{Error, Reason as R};
    use servo_core::CommandError as E;
    match r {
        Reply::Error(Error::Command(E::NotRunning | E::Faulted(_) | E::NotHomed | E::NotCommutated)) => true,
        Reply::Error(Error::ControlledByAnotherClient) => true,
        Reply::Error(Error::Stream { reason }) => {
            matches!(reason, R::RefusedFaultsLatched | R::RefusedNotRunning | R::RefusedNotHomed | R::RefusedNotCommutated | R::StreamGap)
        }
        _ => false,
    }
}

/// Sends the rows as stream points. `paced`: at the rows' times on the
/// wall clock; else back to back (a fast-paced simulated drive steps one
/// stream period per frame). Ends with `Stop` (the drive holds).
pub fn send(client: &mut Client, rows: &[Row], paced: bool) -> Result<StreamReport> {
    send_with(client, rows, paced, false)
}

/// `send`; `track`: with the tracking figures, from telemetry the stream
/// asks for itself (any earlier telemetry setting is replaced, then off).
pub fn send_with(client: &mut Client, rows: &[Row], paced: bool, track: bool) -> Result<StreamReport> {
    send_until(client, rows, paced, track, &std::sync::atomic::AtomicBool::new(false))
}

/// `send_with`, ending early, with `Stop` as ever, once `interrupt` is set
/// (a Ctrl-C handler's flag): the drive holds where its reference rests
/// instead of finding the stream lost.
pub fn send_until(client: &mut Client, rows: &[Row], paced: bool, track: bool, interrupt: &std::sync::atomic::AtomicBool) -> Result<StreamReport> {
    use servo_core::protocol::TelemetryField as F;
    let fields = (1 << F::PositionReference as u32) | (1 << F::MotorPosition as u32) | (1 << F::Faults as u32);
    let tracking = track && client.ask(Request::Telemetry { fields, rate_hz: TRACKING_RATE_HZ }).is_ok();
    if tracking {
        client.telemetry.clear();
    }
    let t0 = Instant::now();
    let mut seq_row = HashMap::new();
    let mut aborted_at_row = None;
    let mut interrupted_at_row = None;
    let interrupted = || interrupt.load(std::sync::atomic::Ordering::Relaxed);
    for (i, r) in rows.iter().enumerate() {
        if interrupted() {
            interrupted_at_row = Some(i + 1);
            break;
        }
        if let Some(u) = client.unsolicited.iter().find(|u| stops_stream(&u.error)) {
            aborted_at_row = Some(seq_row.get(&u.seq).copied().unwrap_or(i + 1));
            break;
        }
        if paced {
            let due = Duration::from_secs_f64((r.t_s - rows[0].t_s).max(0.0));
            while t0.elapsed() < due && !interrupted() {
                client.poll(Duration::ZERO)?;
                let left = due.saturating_sub(t0.elapsed());
                if left > Duration::from_millis(2) {
                    std::thread::sleep(left - Duration::from_millis(1));
                }
            }
        } else if i % 16 == 0 {
            // A look, not a wait: back to back means at the drive's rate.
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
    let wall_s = t0.elapsed().as_secs_f64();
    let mut errs: Vec<f64> = Vec::new();
    let mut trace: Vec<[f64; 3]> = Vec::new();
    if tracking {
        trace = client.telemetry.drain(..).map(|t| [f64::from(t.time_s), f64::from(t.values[0]), f64::from(t.values[1])]).collect();
        errs = trace.iter().map(|r| r[1] - r[2]).collect();
        client.request(Request::Telemetry { fields: 0, rate_hz: 0 })?;
        client.telemetry.clear();
    }
    let faults = match client.request(Request::Status)? {
        Reply::Status(s) => servo_core::FaultSet::from_bits_retain(s.faults).names().map(str::to_string).collect(),
        _ => vec![],
    };
    let rms = (!errs.is_empty()).then(|| (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt() * 1e6);
    let max = (!errs.is_empty()).then(|| errs.iter().fold(0.0f64, |m, e| m.max(e.abs())) * 1e6);
    let mut report = StreamReport {
        rows: rows.len(),
        sent: seq_row.len(),
        aborted_at_row,
        interrupted_at_row,
        duration_s: rows.last().map_or(0.0, |r| r.t_s) - rows[0].t_s,
        wall_s,
        refusals: vec![],
        tracking_rms_um: rms,
        tracking_max_um: max,
        telemetry_records: errs.len(),
        tracking_trace: trace,
        faults,
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

/// The error `stream` ends with when faults are latched: which, why for a
/// lost stream, and the commands that resume.
pub fn fault_advice(name: &str, faults: &[String]) -> String {
    let lost = if faults.iter().any(|f| f == "stream_timeout") {
        " (stream_timeout: no point reached the drive for more than one setpoint interval, the client paused or the link broke, and the drive stopped the rod)"
    } else {
        ""
    };
    format!(
        "{name}: faults latched: {}{lost}; next: `cmd clear-faults`, then `cmd enable`, then `stream` again (its first point is reached from where the rod is)",
        faults.join(", ")
    )
}
