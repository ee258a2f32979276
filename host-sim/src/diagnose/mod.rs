//! `host-sim diagnose`: where the sim-to-real gap lies, which unmodelled
//! effect causes it and how far it shrinks once the effect is added.
//! See `docs/diagnosis.md`.
//!
//! Pipeline: `log` (schema CSV, defmt telemetry, `cranfield` converter,
//! validation) → `residual` (inverse dynamics against the nominal model:
//! torque, position and voltage channels) → `regions`/`spectrum` (where) →
//! `effects` + `fit` (which, trained on one part and scored on a held-out
//! part) → `report` (markdown, PNG, summary.json).

pub mod cranfield;
pub mod effects;
pub mod fit;
pub mod log;
pub mod regions;
pub mod replay;
pub mod report;
pub mod residual;
pub mod spectrum;

use anyhow::{bail, Context, Result};
use fit::Term;
use log::{Issue, Log, Severity};
use residual::{Nominal, Segment, CHANNELS, NCH};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// `host-sim diagnose` arguments.
#[derive(clap::Args, Debug, Clone)]
pub struct DiagnoseArgs {
    /// The measured log: schema CSV (`.csv`), defmt telemetry text (other
    /// extensions), or a Cranfield file (`--format cranfield`, or detected).
    #[arg(long)]
    pub log: PathBuf,
    /// A second log used only as the held-out part (a different run or
    /// trajectory). Without it, alternate runs of --log are held out (or the
    /// last 40 % of a single run).
    #[arg(long)]
    pub heldout: Option<PathBuf>,
    /// Rig file (TOML [control] + [plant]) giving the nominal model; default:
    /// the shipped nominal rig.
    #[arg(long)]
    pub rig: Option<PathBuf>,
    /// Healthy reference log: fit a regression nominal on it instead of the
    /// rig's physics (for rigs whose parameters are unknown, e.g. Cranfield).
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Input format: auto, csv, defmt or cranfield.
    #[arg(long, default_value = "auto")]
    pub format: String,
    /// Also run the closed-loop replay (nominal plant + control core driven
    /// by the logged reference and load) on the first run of --log.
    #[arg(long)]
    pub replay: bool,
    /// Longest stretch replayed, seconds.
    #[arg(long, default_value_t = 60.0)]
    pub replay_max_s: f64,
    /// Only convert --log to the schema CSV (DIR/log.csv) and validate it.
    #[arg(long)]
    pub convert_only: bool,
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// Reads a log in the given format.
pub fn read_log(path: &Path, format: &str) -> Result<Log> {
    let fmt = if format == "auto" {
        let head = std::fs::read_to_string(path)
            .with_context(|| format!("reading {}", path.display()))?
            .lines()
            .next()
            .unwrap_or("")
            .to_string();
        if head.contains("position_error") && head.contains("set_point") {
            "cranfield"
        } else if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")) {
            "csv"
        } else {
            "defmt"
        }
    } else {
        format
    };
    match fmt {
        "csv" => Log::read_csv(path),
        "defmt" => {
            let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
            log::parse_defmt(&text, &path.display().to_string())
        }
        "cranfield" => Ok(cranfield::convert(path)?.log),
        other => bail!("--format {other}: expected auto, csv, defmt or cranfield"),
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct RankEntry {
    pub effect: String,
    pub description: String,
    pub params: BTreeMap<String, f64>,
    /// Weighted over all residual channels (the ranking score).
    pub heldout_gap_shrink_pct: f64,
    /// RMS residual shrink per channel on the held-out part, %.
    pub heldout_shrink_by_channel: BTreeMap<String, f64>,
    /// Fit % of the primary channel on the held-out part.
    pub heldout_fit_before: f64,
    pub heldout_fit_after: f64,
    pub heldout_fit_after_by_channel: BTreeMap<String, f64>,
    pub train_gap_shrink_pct: f64,
    pub indistinguishable_from: Vec<String>,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct NotRanked {
    pub effect: String,
    pub status: String,
    pub reason: String,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct ChannelAnalysis {
    pub channel: String,
    pub fit_train_pct: f64,
    pub fit_heldout_pct: f64,
    pub residual_rms: f64,
    pub regions: Vec<regions::RegionStat>,
    pub bands: Vec<spectrum::Band>,
    pub windows: Vec<spectrum::Window>,
    pub correlation: spectrum::Correlation,
}

/// One region of a channel: the log's RMS residual against the healthy
/// reference log's, both against the same nominal.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RegionComparison {
    pub channel: String,
    pub split: String,
    pub region: String,
    pub rms_log: f64,
    pub rms_reference: f64,
    pub ratio: f64,
    pub mean_log: f64,
    pub mean_reference: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct Summary {
    pub source: String,
    pub heldout_source: Option<String>,
    pub nominal: String,
    pub samples: usize,
    pub train_segments: usize,
    pub heldout_segments: usize,
    pub edge_samples_per_segment_end: usize,
    pub ruled_out: Vec<String>,
    pub issues: Vec<Issue>,
    pub channels: Vec<ChannelAnalysis>,
    /// With a reference (healthy) log: where this log differs from it.
    pub reference_comparison: Vec<RegionComparison>,
    pub primary_channel: String,
    pub top_effect: Option<String>,
    pub ranking: Vec<RankEntry>,
    pub not_ranked: Vec<NotRanked>,
    pub indistinguishable: Vec<(String, String)>,
    pub heldout_fit_before: f64,
    pub heldout_fit_after: f64,
    /// Held-out RMS shrink of the primary channel with the top effect, %.
    pub gap_shrink_pct: f64,
    /// The same over all channels, weighted (the ranking score), %.
    pub gap_shrink_weighted_pct: f64,
    pub stack: Vec<String>,
    pub stack_params: BTreeMap<String, f64>,
    pub heldout_fit_after_stack: f64,
    pub gap_shrink_stack_pct: f64,
    pub gap_shrink_stack_weighted_pct: f64,
    pub wall_s: f64,
    /// Closed-loop replay (with `--replay`).
    pub replay: Option<replay::Replay>,
}

/// Everything the report needs besides the summary.
pub struct Diagnosis {
    pub summary: Summary,
    pub nominal: Nominal,
    pub segments: Vec<Segment>,
    pub primary: usize,
    /// Top-effect and stack terms with their parameters.
    pub top: Option<(Vec<Term>, Vec<f64>)>,
    pub stack: Option<(Vec<Term>, Vec<f64>)>,
}

impl Diagnosis {
    pub fn train(&self) -> Vec<&Segment> {
        self.segments.iter().filter(|s| !s.heldout).collect()
    }
    pub fn heldout(&self) -> Vec<&Segment> {
        self.segments.iter().filter(|s| s.heldout).collect()
    }
}

/// Splits a single long segment into 60 % / 40 %.
fn split_segments(mut segs: Vec<Segment>) -> Vec<Segment> {
    if segs.len() >= 2 {
        for (k, s) in segs.iter_mut().enumerate() {
            s.heldout = k % 2 == 1;
        }
        return segs;
    }
    let Some(s) = segs.pop() else { return segs };
    let cut = s.len() * 3 / 5;
    let take = |a: usize, b: usize, held: bool| {
        let sl = |v: &Vec<f64>| v[a..b].to_vec();
        Segment {
            run: s.run,
            heldout: held,
            first_row: s.first_row + a,
            t: sl(&s.t),
            t_rel: sl(&s.t_rel),
            theta: sl(&s.theta),
            omega: sl(&s.omega),
            alpha: sl(&s.alpha),
            x: sl(&s.x),
            v: sl(&s.v),
            a: sl(&s.a),
            v_ref: sl(&s.v_ref),
            a_ref: sl(&s.a_ref),
            f_load: sl(&s.f_load),
            f_ax: sl(&s.f_ax),
            iq: sl(&s.iq),
            dir: sl(&s.dir),
            since_reversal_s: sl(&s.since_reversal_s),
            c_loc: sl(&s.c_loc),
            input: sl(&s.input),
            y: std::array::from_fn(|c| s.y[c].as_ref().map(sl)),
            r: std::array::from_fn(|c| s.r[c].as_ref().map(sl)),
            encoder: s.encoder,
            rod_from_scale: s.rod_from_scale,
            play: s.play.iter().map(sl).collect(),
            flank: if s.flank.is_empty() { Vec::new() } else { sl(&s.flank) },
            motion_weight: if s.motion_weight.is_empty() { Vec::new() } else { sl(&s.motion_weight) },
            sg_m: s.sg_m,
            dt: s.dt,
        }
    };
    vec![take(0, cut, false), take(cut, s.len(), true)]
}

fn shrink(before: f64, after: f64) -> f64 {
    if before > 0.0 {
        100.0 * (1.0 - after / before)
    } else {
        0.0
    }
}

/// Held-out shrink (primary channel, %) below which no effect is named.
pub const MIN_FINDING_PCT: f64 = 5.0;

/// A ranked effect: its entry, terms, parameters and held-out prediction.
type Ranked = (RankEntry, Vec<Term>, Vec<f64>, Vec<fit::ChannelPred>);

/// The diagnosis of `log` (and optional held-out log) against `nominal`.
pub fn diagnose(log: &Log, heldout: Option<&Log>, nominal: Nominal, tilt_default_deg: f64) -> Result<Diagnosis> {
    diagnose_against(log, heldout, None, nominal, tilt_default_deg)
}

/// `diagnose`, comparing region by region with a healthy `reference` log.
pub fn diagnose_against(
    log: &Log,
    heldout: Option<&Log>,
    reference: Option<&Log>,
    nominal: Nominal,
    tilt_default_deg: f64,
) -> Result<Diagnosis> {
    let t0 = std::time::Instant::now();
    let mut issues = log.issues.clone();
    if let Some(h) = heldout {
        issues.extend(h.issues.iter().cloned().map(|mut i| {
            i.message = format!("held-out log: {}", i.message);
            i
        }));
    }
    if issues.iter().any(|i| i.severity == Severity::Error) {
        let list: Vec<String> =
            issues.iter().filter(|i| i.severity == Severity::Error).map(|i| i.to_string()).collect();
        bail!(
            "{}: the log has {} error(s); nothing is dropped silently, fix them first:\n  {}",
            log.source,
            list.len(),
            list.join("\n  ")
        );
    }
    let mut segments = residual::build_segments(log, &nominal, tilt_default_deg)?;
    if let Some(h) = heldout {
        for s in &mut segments {
            s.heldout = false;
        }
        let mut hs = residual::build_segments(h, &nominal, tilt_default_deg)?;
        for s in &mut hs {
            s.heldout = true;
        }
        segments.extend(hs);
    } else {
        segments = split_segments(segments);
    }
    let train: Vec<&Segment> = segments.iter().filter(|s| !s.heldout).collect();
    let held: Vec<&Segment> = segments.iter().filter(|s| s.heldout).collect();
    if train.is_empty() || held.is_empty() {
        bail!("{}: too little data for a training and a held-out part", log.source);
    }
    let dt = train[0].t.get(1).map_or(1e-3, |t1| t1 - train[0].t[0]);
    let w = fit::channel_weights(&train);
    let gap_before_h = fit::gap(&held, None, &w);
    let gap_before_t = fit::gap(&train, None, &w);
    let fit_before_h = fit::fit_pct(&held, None);
    let fit_before_t = fit::fit_pct(&train, None);

    // Every effect: fit on train, score on held-out.
    let mut ranked: Vec<Ranked> = Vec::new();
    let mut not_ranked = Vec::new();
    for eff in effects::ALL {
        if let Some(why) = eff.not_applicable(train[0], &nominal) {
            not_ranked.push(NotRanked { effect: eff.name().into(), status: "not_applicable".into(), reason: why });
            continue;
        }
        match fit::fit_effect(eff, &train, &nominal, &w) {
            Err(why) => {
                not_ranked.push(NotRanked { effect: eff.name().into(), status: "not_converged".into(), reason: why })
            }
            Ok(f) if fit::unexcited(&f.terms, &train, &held, &nominal, &w).is_some() => {
                let name = fit::unexcited(&f.terms, &train, &held, &nominal, &w).unwrap_or_default();
                not_ranked.push(NotRanked {
                    effect: eff.name().into(),
                    status: "not_converged".into(),
                    reason: format!(
                        "parameter `{name}` is not identifiable: the training part does not excite it (under 1 % of its held-out excitation)"
                    ),
                });
            }
            Ok(f) => {
                let pred: Vec<_> = held.iter().map(|s| fit::predict(&f.terms, &f.params, s, &nominal)).collect();
                let g = fit::gap(&held, Some(&pred), &w);
                let fa = fit::fit_pct(&held, Some(&pred));
                let mut params: BTreeMap<String, f64> =
                    eff.params().iter().zip(&f.params).map(|(n, v)| (n.to_string(), *v)).collect();
                if let Some((gname, _)) = eff.grid_for(&nominal) {
                    params.insert(gname.into(), f.terms[0].hyper);
                }
                let entry = RankEntry {
                    effect: eff.name().into(),
                    description: eff.description().into(),
                    params,
                    heldout_gap_shrink_pct: shrink(gap_before_h, g),
                    heldout_shrink_by_channel: (0..NCH)
                        .filter(|c| fit_before_h[*c].is_some())
                        .map(|c| {
                            let mut wc = [0.0; NCH];
                            wc[c] = 1.0;
                            (
                                CHANNELS[c].to_string(),
                                shrink(fit::gap(&held, None, &wc), fit::gap(&held, Some(&pred), &wc)),
                            )
                        })
                        .collect(),
                    heldout_fit_before: 0.0,
                    heldout_fit_after: 0.0,
                    heldout_fit_after_by_channel: (0..NCH)
                        .filter_map(|c| fa[c].map(|v| (CHANNELS[c].to_string(), v)))
                        .collect(),
                    train_gap_shrink_pct: shrink(gap_before_t, f.train_gap),
                    indistinguishable_from: Vec::new(),
                };
                ranked.push((entry, f.terms, f.params, pred));
            }
        }
    }
    ranked.sort_by(|a, b| b.0.heldout_gap_shrink_pct.total_cmp(&a.0.heldout_gap_shrink_pct));

    // Primary channel: where the top effect removes the most, else the
    // channel with the worst held-out fit.
    let avail: Vec<usize> = (0..NCH).filter(|c| fit_before_h[*c].is_some()).collect();
    let primary = match ranked.first() {
        Some((_, terms, params, pred)) => {
            let _ = (terms, params);
            *avail
                .iter()
                .max_by(|a, b| {
                    let gain = |c: usize| {
                        let before: f64 = held
                            .iter()
                            .filter_map(|s| Some((s, s.r[c].as_ref()?)))
                            .flat_map(|(s, r)| r.iter().enumerate().map(move |(i, x)| (s.weight(c, i) * x).powi(2)))
                            .sum();
                        let after: f64 = held
                            .iter()
                            .zip(pred)
                            .filter_map(|(s, p)| Some((s, s.r[c].as_ref()?, p[c].as_ref()?)))
                            .flat_map(|(s, r, p)| {
                                r.iter().zip(p).enumerate().map(move |(i, (a, b))| (s.weight(c, i) * (a - b)).powi(2))
                            })
                            .sum();
                        (before - after) * w[c] * w[c]
                    };
                    gain(**a).total_cmp(&gain(**b))
                })
                .unwrap_or(&0)
        }
        None => {
            *avail.iter().min_by(|a, b| fit_before_h[**a].unwrap().total_cmp(&fit_before_h[**b].unwrap())).unwrap_or(&0)
        }
    };
    for r in &mut ranked {
        r.0.heldout_fit_before = fit_before_h[primary].unwrap_or(f64::NAN);
        r.0.heldout_fit_after = r.0.heldout_fit_after_by_channel.get(CHANNELS[primary]).copied().unwrap_or(f64::NAN);
    }

    // Indistinguishable pairs: weighted predictions correlate > 0.95 on the
    // held-out part, or scores within 1 point, both explaining > 10 %.
    let mut indist = Vec::new();
    let corr = |pa: &[fit::ChannelPred], pb: &[fit::ChannelPred]| {
        let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
        for (x, y) in pa.iter().zip(pb) {
            for c in 0..NCH {
                if let (Some(x), Some(y)) = (&x[c], &y[c]) {
                    for (u, v) in x.iter().zip(y) {
                        ab += u * v * w[c] * w[c];
                        aa += u * u * w[c] * w[c];
                        bb += v * v * w[c] * w[c];
                    }
                }
            }
        }
        if aa > 0.0 && bb > 0.0 {
            ab / (aa * bb).sqrt()
        } else {
            0.0
        }
    };
    for a in 0..ranked.len() {
        for b in a + 1..ranked.len() {
            let (sa, sb) = (ranked[a].0.heldout_gap_shrink_pct, ranked[b].0.heldout_gap_shrink_pct);
            if sa < 10.0 || sb < 10.0 {
                continue;
            }
            if corr(&ranked[a].3, &ranked[b].3).abs() > 0.95 || (sa - sb).abs() < 1.0 {
                let (na, nb) = (ranked[a].0.effect.clone(), ranked[b].0.effect.clone());
                ranked[a].0.indistinguishable_from.push(nb.clone());
                ranked[b].0.indistinguishable_from.push(na.clone());
                indist.push((na, nb));
            }
        }
    }

    // Greedy stacking on the held-out gap.
    // A finding: the best effect removes at least `MIN_FINDING_PCT` of the
    // held-out gap in its channel; below that no effect is named.
    let top = ranked
        .first()
        .filter(|r| {
            r.0.heldout_gap_shrink_pct > 0.0
                && r.0.heldout_shrink_by_channel.get(CHANNELS[primary]).is_some_and(|v| *v >= MIN_FINDING_PCT)
        })
        .map(|r| (r.1.clone(), r.2.clone()));
    let mut stack_terms: Vec<Term> = top.as_ref().map(|t| t.0.clone()).unwrap_or_default();
    let mut stack_params = top.as_ref().map(|t| t.1.clone()).unwrap_or_default();
    let mut stack_gap = ranked
        .first()
        .filter(|_| top.is_some())
        .map_or(gap_before_h, |r| gap_before_h * (1.0 - r.0.heldout_gap_shrink_pct / 100.0));
    if top.is_some() {
        for _ in 0..3 {
            let mut best: Option<(Vec<Term>, Vec<f64>, f64)> = None;
            for cand in ranked.iter().skip(1) {
                if cand.0.heldout_gap_shrink_pct <= 1.0 || stack_terms.iter().any(|t| t.effect == cand.1[0].effect) {
                    continue;
                }
                let mut terms = stack_terms.clone();
                terms.extend(cand.1.iter().copied());
                if let Ok(p) = fit::fit_terms(&terms, &train, &nominal, &w) {
                    let pred: Vec<_> = held.iter().map(|s| fit::predict(&terms, &p, s, &nominal)).collect();
                    let g = fit::gap(&held, Some(&pred), &w);
                    if best.as_ref().is_none_or(|b| g < b.2) {
                        best = Some((terms, p, g));
                    }
                }
            }
            match best {
                Some((t, p, g)) if shrink(stack_gap, g) >= 5.0 => {
                    stack_terms = t;
                    stack_params = p;
                    stack_gap = g;
                }
                _ => break,
            }
        }
    }
    let stack = (!stack_terms.is_empty()).then(|| (stack_terms.clone(), stack_params.clone()));
    let mut wp = [0.0; NCH];
    wp[primary] = 1.0;
    let (stack_fit, stack_primary_shrink) = match &stack {
        Some((t, p)) => {
            let pred: Vec<_> = held.iter().map(|s| fit::predict(t, p, s, &nominal)).collect();
            (
                fit::fit_pct(&held, Some(&pred))[primary].unwrap_or(f64::NAN),
                shrink(fit::gap(&held, None, &wp), fit::gap(&held, Some(&pred), &wp)),
            )
        }
        None => (fit_before_h[primary].unwrap_or(f64::NAN), 0.0),
    };
    let mut sp = BTreeMap::new();
    let mut k = 0;
    for t in &stack_terms {
        for n in t.effect.params() {
            sp.insert(format!("{}.{}", t.effect.name(), n), stack_params[k]);
            k += 1;
        }
    }

    // Where the gap lies, per channel (all data, nominal residual).
    let all: Vec<&Segment> = segments.iter().collect();
    let channels: Vec<ChannelAnalysis> = avail
        .iter()
        .map(|&c| {
            let (f, p) = spectrum::welch(&all, c);
            let rms = (all.iter().filter_map(|s| s.r[c].as_ref()).flat_map(|r| r.iter().map(|x| x * x)).sum::<f64>()
                / all.iter().map(|s| s.len()).sum::<usize>().max(1) as f64)
                .sqrt();
            ChannelAnalysis {
                channel: CHANNELS[c].into(),
                fit_train_pct: fit_before_t[c].unwrap_or(f64::NAN),
                fit_heldout_pct: fit_before_h[c].unwrap_or(f64::NAN),
                residual_rms: rms,
                regions: regions::split(&all, c),
                bands: spectrum::bands(&f, &p),
                windows: spectrum::top_windows(&all, c, (0.5f64).max(20.0 * dt), 5),
                correlation: spectrum::correlation(&all, c, 25),
            }
        })
        .collect();
    let mut reference_comparison = Vec::new();
    if let Some(rl) = reference {
        let rsegs = residual::build_segments(rl, &nominal, tilt_default_deg)?;
        let rrefs: Vec<&Segment> = rsegs.iter().collect();
        for &c in &avail {
            let mine = regions::split_basis(&all, &all, c);
            let theirs = regions::split_basis(&rrefs, &all, c);
            for m in mine {
                if let Some(t) = theirs.iter().find(|t| t.split == m.split && t.region == m.region) {
                    reference_comparison.push(RegionComparison {
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
    }
    let top_entry = ranked.first().filter(|_| top.is_some()).map(|r| r.0.clone());
    let summary = Summary {
        source: log.source.clone(),
        heldout_source: heldout.map(|h| h.source.clone()),
        nominal: match &nominal {
            Nominal::Physics(_) => "rig physics ([plant] of the rig TOML)".into(),
            Nominal::Regression(r) => format!("regression fitted on the reference log: {}", serde_json::to_string(r)?),
        },
        samples: log.len() + heldout.map_or(0, Log::len),
        train_segments: train.len(),
        heldout_segments: held.len(),
        edge_samples_per_segment_end: residual::half_width(dt),
        ruled_out: log.ruled_out(),
        issues,
        channels,
        reference_comparison,
        primary_channel: CHANNELS[primary].into(),
        top_effect: top.as_ref().map(|t| t.0[0].effect.name().to_string()),
        heldout_fit_before: fit_before_h[primary].unwrap_or(f64::NAN),
        heldout_fit_after: top_entry
            .as_ref()
            .map_or(fit_before_h[primary].unwrap_or(f64::NAN), |e| e.heldout_fit_after),
        gap_shrink_pct: top_entry
            .as_ref()
            .and_then(|e| e.heldout_shrink_by_channel.get(CHANNELS[primary]).copied())
            .map_or(0.0, |v| v.max(0.0)),
        gap_shrink_weighted_pct: top_entry.as_ref().map_or(0.0, |e| e.heldout_gap_shrink_pct.max(0.0)),
        ranking: ranked.iter().map(|r| r.0.clone()).collect(),
        not_ranked,
        indistinguishable: indist,
        stack: stack_terms.iter().map(|t| t.effect.name().to_string()).collect(),
        stack_params: sp,
        heldout_fit_after_stack: stack_fit,
        gap_shrink_stack_pct: stack_primary_shrink.max(0.0),
        gap_shrink_stack_weighted_pct: shrink(gap_before_h, stack_gap).max(0.0),
        wall_s: t0.elapsed().as_secs_f64(),
        replay: None,
    };
    drop(train);
    drop(held);
    drop(all);
    Ok(Diagnosis { summary, nominal, segments, primary, top, stack })
}

/// `host-sim diagnose`.
pub fn run_cli(args: &DiagnoseArgs) -> Result<()> {
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let log = read_log(&args.log, &args.format)?;
    for i in &log.issues {
        eprintln!("{}: {i}", log.source);
    }
    if args.convert_only {
        let path = args.out.join("log.csv");
        log.write_csv(&path)?;
        println!("wrote {} ({} rows, {} errors)", path.display(), log.len(), log.errors().count());
        return if log.errors().count() > 0 { bail!("the converted log has errors (listed above)") } else { Ok(()) };
    }
    let heldout = args.heldout.as_ref().map(|p| read_log(p, &args.format)).transpose()?;
    let rig = crate::config::RigConfig::load_or_nominal(args.rig.as_ref())?;
    let reference = args.reference.as_ref().map(|p| read_log(p, &args.format)).transpose()?;
    let nominal = match &reference {
        Some(r) => Nominal::Regression(residual::fit_regression(r)?),
        None => Nominal::Physics(residual::Physics::from_rig(&rig)),
    };
    let mut d = diagnose_against(&log, heldout.as_ref(), reference.as_ref(), nominal, rig.plant.load.initial_tilt_deg)?;
    if args.replay {
        match replay::replay(&rig, &log, args.replay_max_s) {
            Ok(r) => d.summary.replay = Some(r),
            Err(e) => eprintln!("replay skipped: {e:#}"),
        }
    }
    report::write(&d, &args.out)?;
    let s = &d.summary;
    println!(
        "top effect: {} (held-out gap shrink {:.1} %, fit {:.1} → {:.1} % on the {} channel); stack {:?}: {:.1} %",
        s.top_effect.as_deref().unwrap_or("none"),
        s.gap_shrink_pct,
        s.heldout_fit_before,
        s.heldout_fit_after,
        s.primary_channel,
        s.stack,
        s.gap_shrink_stack_pct
    );
    println!("wrote {}/{{report.md, summary.json, *.png}}", args.out.display());
    Ok(())
}
