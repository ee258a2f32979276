//! The disturbance's events as a user reads them off their rig: an
//! onset, an offset and one level between them, each with its
//! uncertainty. An unmeasured force is absent most of the time, so the
//! baseline is the level the log spends most of its time at (the
//! duration-weighted median of the interval levels); an event is a run of
//! consecutive intervals whose levels leave the baseline on the same
//! side by more than `DEPART_SIGMA` of their uncertainty. An event that
//! runs into a segment's start or end has no onset or offset there: the
//! log does not see it.

use super::Interval;

/// A level departs from the baseline by more than this many of its
/// sigmas.
pub const DEPART_SIGMA: f64 = 3.0;

#[derive(Clone, Debug, Default, serde::Serialize, PartialEq)]
pub struct Event {
    pub run: usize,
    /// Onset (s) and its 1-sigma uncertainty; `None` where the event was
    /// already on at the segment's start.
    pub onset_s: Option<f64>,
    pub onset_sd_s: Option<f64>,
    /// Offset (s) and its 1-sigma uncertainty; `None` where it was still
    /// on at the segment's end.
    pub offset_s: Option<f64>,
    pub offset_sd_s: Option<f64>,
    /// Level from the baseline (the disturbance's level unit), duration
    /// weighted over the event's intervals, and its 1-sigma uncertainty
    /// (`None` where an interval is too short to tell).
    pub level: f64,
    pub level_sd: Option<f64>,
}

/// Duration-weighted median of the levels.
fn baseline(iv: &[Interval]) -> f64 {
    let mut v: Vec<(f64, f64)> = iv.iter().map(|i| (i.level, i.end_s - i.start_s)).collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = v.iter().map(|x| x.1).sum();
    let mut acc = 0.0;
    for (l, d) in &v {
        acc += d;
        if acc >= 0.5 * total {
            return *l;
        }
    }
    0.0
}

/// The events of the intervals (in time order per run, one channel).
pub fn events(iv: &[Interval]) -> Vec<Event> {
    let base = baseline(iv);
    let side = |i: &Interval| -> i8 {
        let d = i.level - base;
        match i.level_sd {
            Some(sd) if d.abs() <= DEPART_SIGMA * sd => 0,
            _ if d == 0.0 => 0,
            _ => d.signum() as i8,
        }
    };
    let mut out = Vec::new();
    let mut j = 0;
    while j < iv.len() {
        let sd0 = side(&iv[j]);
        if sd0 == 0 {
            j += 1;
            continue;
        }
        // Consecutive: same run, and the next begins at a fitted edge
        // (not a new segment).
        let mut e = j + 1;
        while e < iv.len() && iv[e].run == iv[j].run && iv[e].start_sd_s.is_some() && side(&iv[e]) == sd0 {
            e += 1;
        }
        let run = &iv[j..e];
        let dur: f64 = run.iter().map(|i| i.end_s - i.start_s).sum();
        let level = run.iter().map(|i| (i.level - base) * (i.end_s - i.start_s)).sum::<f64>() / dur;
        let level_sd = run
            .iter()
            .map(|i| i.level_sd.map(|s| (s * (i.end_s - i.start_s) / dur).powi(2)))
            .sum::<Option<f64>>()
            .map(f64::sqrt);
        let closed = iv.get(e).is_some_and(|n| n.run == iv[j].run && n.start_sd_s.is_some());
        out.push(Event {
            run: iv[j].run,
            onset_s: iv[j].start_sd_s.map(|_| iv[j].start_s),
            onset_sd_s: iv[j].start_sd_s,
            offset_s: closed.then(|| iv[e - 1].end_s),
            offset_sd_s: if closed { iv[e].start_sd_s } else { None },
            level,
            level_sd,
        });
        j = e;
    }
    out
}

/// The events as a markdown table (the first `MAX_ROWS`), times in s with
/// their 1-sigma in ms.
pub fn table(ev: &[Event], unit: &str) -> String {
    use std::fmt::Write;
    const MAX_ROWS: usize = 40;
    let t = |v: Option<f64>, sd: Option<f64>| match (v, sd) {
        (Some(v), Some(sd)) => format!("{v:.3} ± {:.1} ms", 1e3 * sd),
        (Some(v), None) => format!("{v:.3}"),
        _ => "—".into(),
    };
    let mut out = format!("Events ({} departures from the baseline level; level in {unit}, ± 1 σ):\n\n| run | onset s | offset s | level |\n|---|---|---|---|\n", ev.len());
    for e in ev.iter().take(MAX_ROWS) {
        let lv = match e.level_sd {
            Some(sd) => format!("{:.4e} ± {:.1e}", e.level, sd),
            None => format!("{:.4e}", e.level),
        };
        let _ = writeln!(out, "| {} | {} | {} | {lv} |", e.run, t(e.onset_s, e.onset_sd_s), t(e.offset_s, e.offset_sd_s));
    }
    if ev.len() > MAX_ROWS {
        let _ = writeln!(out, "\n({} more in summary.json)", ev.len() - MAX_ROWS);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn iv(run: usize, a: f64, e: f64, level: f64, edge: bool) -> Interval {
        Interval { channel: 0, run, start_s: a, end_s: e, level, start_sd_s: edge.then_some(0.001), level_sd: Some(1.0) }
    }

    /// Two pulses of 100 on a zero baseline, the second running into the
    /// segment's end: the first has both edges, the second no offset.
    #[test]
    fn pulses_on_a_baseline_are_events_with_their_edges() {
        let v = [
            iv(0, 0.0, 1.0, 0.5, false),
            iv(0, 1.0, 1.2, 100.5, true),
            iv(0, 1.2, 3.0, 0.5, true),
            iv(0, 3.0, 3.3, -50.5, true),
        ];
        let e = events(&v);
        assert_eq!(e.len(), 2);
        assert_eq!((e[0].onset_s, e[0].offset_s), (Some(1.0), Some(1.2)));
        assert!((e[0].level - 100.0).abs() < 1e-9);
        assert_eq!((e[1].onset_s, e[1].offset_s), (Some(3.0), None));
        assert!((e[1].level + 51.0).abs() < 1e-9);
    }

    /// A level within its uncertainty of the baseline is no event.
    #[test]
    fn a_level_within_its_sigma_is_no_event() {
        let v = [iv(0, 0.0, 1.0, 0.0, false), iv(0, 1.0, 1.1, 2.0, true), iv(0, 1.1, 3.0, 0.0, true)];
        assert!(events(&v).is_empty());
    }
}
