//! Ranking the library on the held-out part, the indistinguishable pairs
//! and the greedy stack.

use super::effects::Effect;
use super::figures::shrink;
use super::fit::{self, ChannelPred, Term};
use super::residual::{Nominal, Segment, CHANNELS, NCH};
use super::summary::{NotRanked, RankEntry};
use super::{plausible, MIN_FINDING_PCT};
use std::collections::BTreeMap;

/// A ranked effect: its entry, terms, parameters and held-out prediction.
pub type Ranked = (RankEntry, Vec<Term>, Vec<f64>, Vec<ChannelPred>);

pub struct Ranking {
    pub ranked: Vec<Ranked>,
    pub not_ranked: Vec<NotRanked>,
    pub primary: usize,
    pub indist: Vec<(String, String)>,
    pub top: Option<(Vec<Term>, Vec<f64>)>,
    pub stack_terms: Vec<Term>,
    pub stack_params: Vec<f64>,
    /// Weighted held-out gap after the stack (the nominal's without one).
    pub stack_gap: f64,
    /// The top effect refitted on the first and on the second half (in
    /// time) of every training segment: its held-out primary-channel
    /// shrink with each, and the change of its first parameter between
    /// the halves relative to the full fit's.
    pub top_halves: Option<(f64, f64, f64)>,
}

/// A cause must keep at least this share of its held-out shrink when
/// fitted on either half of the training run alone: an effect whose
/// parameters drift over the run (a torque constant falling as the
/// magnets warm, fitted as a current-sensor gain) stands in for something
/// time-varying and is not a constant-parameter library effect.
pub const STABLE_SHARE: f64 = 0.7;
/// … or whose leading parameter changes between the halves by more than
/// this share of its full-run value.
pub const STABLE_PARAM_CHANGE: f64 = 0.4;

/// Weighted held-out shrink of channel `c` alone.
pub fn channel_shrink(held: &[&Segment], pred: Option<&[ChannelPred]>, c: usize) -> f64 {
    let mut wc = [0.0; NCH];
    wc[c] = 1.0;
    shrink(fit::gap(held, None, &wc), fit::gap(held, pred, &wc))
}

pub fn rank(
    library: &[Effect],
    train: &[&Segment],
    held: &[&Segment],
    nominal: &Nominal,
    w: &[f64; NCH],
) -> Ranking {
    let gap_before_h = fit::gap(held, None, w);
    let gap_before_t = fit::gap(train, None, w);
    let fit_before_h = fit::fit_pct(held, None);
    let mut ranked: Vec<Ranked> = Vec::new();
    let mut not_ranked = Vec::new();
    for &eff in library {
        let nr = |status: &str, reason: String| NotRanked {
            effect: eff.name().into(),
            status: status.into(),
            reason,
        };
        if let Some(why) = eff.not_applicable(train[0], nominal) {
            not_ranked.push(nr("not_applicable", why));
            continue;
        }
        let f = match fit::fit_effect(eff, train, nominal, w) {
            Err(why) => {
                not_ranked.push(nr("not_converged", why));
                continue;
            }
            Ok(f) => f,
        };
        if let Some(name) = fit::unexcited(&f.terms, train, held, nominal, w) {
            not_ranked.push(nr(
                "not_converged",
                format!("parameter `{name}` is not identifiable: the training part does not excite it (under 1 % of its held-out excitation)"),
            ));
            continue;
        }
        if let Some(why) = plausible::check(eff, &f.params, nominal, train) {
            not_ranked.push(nr("implausible", why));
            continue;
        }
        let pred: Vec<_> = held
            .iter()
            .map(|s| fit::predict(&f.terms, &f.params, s, nominal))
            .collect();
        let g = fit::gap(held, Some(&pred), w);
        let fa = fit::fit_pct(held, Some(&pred));
        let mut params: BTreeMap<String, f64> = eff
            .params_for(nominal)
            .into_iter()
            .zip(f.params.iter().copied())
            .collect();
        if let Some(gname) = eff.grid_name_for(nominal) {
            params.insert(gname.into(), f.terms[0].hyper);
        }
        let entry = RankEntry {
            effect: eff.name().into(),
            description: eff.description().into(),
            params,
            weighted_shrink_pct: shrink(gap_before_h, g),
            primary_shrink_pct: 0.0,
            heldout_shrink_by_channel: (0..NCH)
                .filter(|c| fit_before_h[*c].is_some())
                .map(|c| {
                    (
                        CHANNELS[c].to_string(),
                        channel_shrink(held, Some(&pred), c),
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
    ranked.sort_by(|a, b| b.0.weighted_shrink_pct.total_cmp(&a.0.weighted_shrink_pct));

    // Primary channel: where the top effect removes the most (weighted
    // energy) — if it is a finding, removing `MIN_FINDING_PCT` of some
    // channel's gap — else the channel with the worst held-out fit. A
    // best-of-nothing effect (every shrink under the floor's noise) says
    // nothing about where the gap is: a dead-time term that trims 1 % of
    // the voltage channel once made that channel "primary" for a force
    // that acts on torque and position only.
    let avail: Vec<usize> = (0..NCH).filter(|c| fit_before_h[*c].is_some()).collect();
    let finding = ranked.first().filter(|r| {
        r.0.weighted_shrink_pct > 0.0
            && r.0
                .heldout_shrink_by_channel
                .values()
                .any(|v| *v >= MIN_FINDING_PCT)
    });
    let primary = match finding {
        Some((_, _, _, pred)) => {
            let gain = |c: usize| {
                let mut wc = [0.0; NCH];
                wc[c] = w[c];
                fit::gap(held, None, &wc).powi(2) - fit::gap(held, Some(pred), &wc).powi(2)
            };
            *avail
                .iter()
                .max_by(|a, b| gain(**a).total_cmp(&gain(**b)))
                .unwrap_or(&0)
        }
        None => *avail
            .iter()
            .min_by(|a, b| {
                fit_before_h[**a]
                    .unwrap_or(0.0)
                    .total_cmp(&fit_before_h[**b].unwrap_or(0.0))
            })
            .unwrap_or(&0),
    };
    for r in &mut ranked {
        r.0.heldout_fit_before = fit_before_h[primary].unwrap_or(f64::NAN);
        r.0.heldout_fit_after =
            r.0.heldout_fit_after_by_channel
                .get(CHANNELS[primary])
                .copied()
                .unwrap_or(f64::NAN);
        r.0.primary_shrink_pct =
            r.0.heldout_shrink_by_channel
                .get(CHANNELS[primary])
                .copied()
                .unwrap_or(0.0);
    }

    // Indistinguishable pairs: weighted predictions correlate > 0.95 on the
    // held-out part, or scores within 1 point, both explaining > 10 %.
    let mut indist = Vec::new();
    let corr = |pa: &[ChannelPred], pb: &[ChannelPred]| {
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
            let (sa, sb) = (
                ranked[a].0.weighted_shrink_pct,
                ranked[b].0.weighted_shrink_pct,
            );
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

    // A finding: the best effect removes at least `MIN_FINDING_PCT` of the
    // held-out gap in its channel; below that no effect is named.
    let top = ranked
        .first()
        .filter(|r| r.0.weighted_shrink_pct > 0.0 && r.0.primary_shrink_pct >= MIN_FINDING_PCT)
        .map(|r| (r.1.clone(), r.2.clone()));
    // Greedy stacking on the held-out gap (joint refit on training).
    let mut stack_terms: Vec<Term> = top.as_ref().map(|t| t.0.clone()).unwrap_or_default();
    let mut stack_params = top.as_ref().map(|t| t.1.clone()).unwrap_or_default();
    let mut stack_gap = ranked
        .first()
        .filter(|_| top.is_some())
        .map_or(gap_before_h, |r| {
            gap_before_h * (1.0 - r.0.weighted_shrink_pct / 100.0)
        });
    if top.is_some() {
        for _ in 0..3 {
            let mut best: Option<(Vec<Term>, Vec<f64>, f64)> = None;
            for cand in ranked.iter().skip(1) {
                if cand.0.weighted_shrink_pct <= 1.0
                    || stack_terms.iter().any(|t| t.effect == cand.1[0].effect)
                {
                    continue;
                }
                let mut terms = stack_terms.clone();
                terms.extend(cand.1.iter().copied());
                if let Ok(p) = fit::fit_terms(&terms, train, nominal, w) {
                    let pred: Vec<_> = held
                        .iter()
                        .map(|s| fit::predict(&terms, &p, s, nominal))
                        .collect();
                    let g = fit::gap(held, Some(&pred), w);
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
    let top_halves = top.as_ref().map(|(terms, _)| {
        let halves: [Vec<Segment>; 2] = std::array::from_fn(|h| {
            train
                .iter()
                .map(|s| {
                    let mid = s.len() / 2;
                    if h == 0 {
                        super::slice_segment(s, 0, mid, false)
                    } else {
                        super::slice_segment(s, mid, s.len(), false)
                    }
                })
                .collect()
        });
        let score = |segs: &Vec<Segment>| {
            let refs: Vec<&Segment> = segs.iter().collect();
            match fit::fit_terms(terms, &refs, nominal, w) {
                Ok(p) => {
                    let pred: Vec<_> = held
                        .iter()
                        .map(|s| fit::predict(terms, &p, s, nominal))
                        .collect();
                    (
                        channel_shrink(held, Some(&pred), primary),
                        p.first().copied().unwrap_or(f64::NAN),
                    )
                }
                Err(_) => (f64::NAN, f64::NAN),
            }
        };
        let ((s0, p0), (s1, p1)) = (score(&halves[0]), score(&halves[1]));
        let full = top
            .as_ref()
            .and_then(|t| t.1.first().copied())
            .unwrap_or(f64::NAN);
        (s0, s1, (p1 - p0).abs() / full.abs())
    });
    Ranking {
        ranked,
        not_ranked,
        primary,
        indist,
        top,
        stack_terms,
        stack_params,
        stack_gap,
        top_halves,
    }
}
