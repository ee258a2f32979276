//! What a healthy reference log adds to a diagnosis: the regression
//! nominal judged on the log it was fitted on (a channel it does not hold
//! there is left out), and the residual compared region by region with
//! the reference's under the same nominal.

use super::gates::{self, Gate};
use super::log::Log;
use super::regions;
use super::residual::{self, Nominal, Segment, CHANNELS, NCH};
use super::summary::RegionComparison;
use anyhow::Result;

/// The regression nominal judged on its own reference: a channel it does
/// not hold on is left out of `segments` (its gap would be the
/// regression's); with none left, the baseline is broken
/// (`gates::baseline_broken`). The gates it raises.
pub fn judge_regression(nominal: &Nominal, reference: Option<&Log>, segments: &mut [Segment]) -> Result<Vec<Gate>> {
    let (Nominal::Regression(reg), Some(r)) = (nominal, reference) else {
        return Ok(Vec::new());
    };
    let mut out = gates::reference_gates(r, reg)?;
    let unsound: Vec<usize> = out
        .iter()
        .filter(|g| g.kind == "reference_unsound")
        .filter_map(|g| CHANNELS.iter().position(|c| Some(*c) == g.channel.as_deref()))
        .collect();
    let with_data: Vec<usize> = (0..NCH).filter(|c| segments.iter().any(|s| s.r[*c].is_some())).collect();
    if with_data.iter().any(|c| !unsound.contains(c)) {
        for s in segments.iter_mut() {
            for &c in &unsound {
                s.y[c] = None;
                s.r[c] = None;
            }
        }
        for g in &mut out {
            if g.kind == "reference_unsound" {
                g.kind = "reference_channel_left_out".into();
                g.message.push_str("; this channel is left out of the diagnosis");
            }
        }
    }
    Ok(out)
}

/// The residual of `all` against the reference's, region by region, on
/// the channels `avail`.
pub fn compare_regions(all: &[&Segment], reference: &Log, nominal: &Nominal, tilt_default_deg: f64, avail: &[usize]) -> Result<Vec<RegionComparison>> {
    let rsegs = residual::build_segments(reference, nominal, tilt_default_deg)?;
    let rrefs: Vec<&Segment> = rsegs.iter().collect();
    let mut out = Vec::new();
    for &c in avail {
        let mine = regions::split_basis(all, all, c);
        let theirs = regions::split_basis(&rrefs, all, c);
        for m in mine {
            if let Some(t) = theirs.iter().find(|t| t.split == m.split && t.region == m.region) {
                out.push(RegionComparison {
                    channel: CHANNELS[c].into(),
                    split: m.split.into(),
                    region: m.region.clone(),
                    rms_log: m.rms,
                    rms_reference: t.rms,
                    ratio: if t.rms > 0.0 { m.rms / t.rms } else { f64::NAN },
                    mean_log: m.mean,
                    mean_reference: t.mean,
                });
            }
        }
    }
    Ok(out)
}
