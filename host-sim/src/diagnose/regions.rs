//! Where the gap lies in the operating space: the residual of one channel
//! split by direction, speed band, acceleration phase, load band, stroke
//! position and the neighbourhood of reversals; and a speed × stroke heat map.

use super::residual::Segment;

#[derive(Clone, Debug, serde::Serialize)]
pub struct RegionStat {
    pub split: &'static str,
    pub region: String,
    pub samples: usize,
    pub rms: f64,
    pub mean: f64,
    /// Share of the channel's residual energy in this region, %.
    pub energy_pct: f64,
}

fn quantiles(mut v: Vec<f64>, qs: &[f64]) -> Vec<f64> {
    v.retain(|x| x.is_finite());
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return qs.iter().map(|_| 0.0).collect();
    }
    qs.iter()
        .map(|q| v[((v.len() - 1) as f64 * q) as usize])
        .collect()
}

/// Region label functions over all samples of `segs` for channel `ch`.
pub fn split(segs: &[&Segment], ch: usize) -> Vec<RegionStat> {
    split_basis(segs, segs, ch)
}

/// `split` with the band edges taken from `basis` (to compare two logs
/// region by region).
pub fn split_basis(segs: &[&Segment], basis: &[&Segment], ch: usize) -> Vec<RegionStat> {
    let speed: Vec<f64> = basis
        .iter()
        .flat_map(|s| s.v.iter().map(|v| v.abs()))
        .collect();
    let vmax = speed.iter().fold(0.0f64, |m, v| m.max(*v));
    let moving: Vec<f64> = speed.iter().copied().filter(|v| *v > 0.05 * vmax).collect();
    let vq = quantiles(moving, &[1.0 / 3.0, 2.0 / 3.0]);
    let amax = basis
        .iter()
        .flat_map(|s| s.a.iter())
        .fold(0.0f64, |m, a| m.max(a.abs()));
    let fq = quantiles(
        basis
            .iter()
            .flat_map(|s| s.f_load.iter().copied())
            .collect(),
        &[1.0 / 3.0, 2.0 / 3.0],
    );
    let xq = quantiles(
        basis.iter().flat_map(|s| s.x.iter().copied()).collect(),
        &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0],
    );
    type Label = Box<dyn Fn(&Segment, usize) -> String>;
    let (vq0, vq1, fq0, fq1) = (vq[0], vq[1], fq[0], fq[1]);
    let xq2 = xq.clone();
    let splits: Vec<(&'static str, Label)> = vec![
        (
            "direction",
            Box::new(move |s: &Segment, i| {
                if s.v[i].abs() <= 0.05 * vmax {
                    "standstill".into()
                } else if s.v[i] > 0.0 {
                    "extending (+)".into()
                } else {
                    "retracting (−)".into()
                }
            }),
        ),
        (
            "speed band",
            Box::new(move |s: &Segment, i| {
                let v = s.v[i].abs();
                if v <= 0.05 * vmax {
                    "standstill".into()
                } else if v < vq0 {
                    format!("low (< {:.3} m/s)", vq0)
                } else if v < vq1 {
                    "mid".into()
                } else {
                    format!("high (≥ {:.3} m/s)", vq1)
                }
            }),
        ),
        (
            "acceleration phase",
            Box::new(move |s: &Segment, i| {
                let a = s.a[i] * s.v[i].signum();
                if a.abs() < 0.1 * amax || s.v[i].abs() <= 0.05 * vmax {
                    "constant speed / rest".into()
                } else if a > 0.0 {
                    "accelerating".into()
                } else {
                    "decelerating".into()
                }
            }),
        ),
        (
            "load band",
            Box::new(move |s: &Segment, i| {
                let f = s.f_load[i];
                if f < fq0 {
                    format!("low (< {:.0} N)", fq0)
                } else if f < fq1 {
                    "mid".into()
                } else {
                    format!("high (≥ {:.0} N)", fq1)
                }
            }),
        ),
        (
            "stroke position",
            Box::new(move |s: &Segment, i| {
                let k = (1..5).filter(|k| s.x[i] >= xq2[*k]).count();
                format!("quintile {} ({:.3}–{:.3} m)", k + 1, xq2[k], xq2[k + 1])
            }),
        ),
        (
            "reversal",
            Box::new(|s: &Segment, i| {
                if s.since_reversal_s[i] < 0.15 && s.t_rel[i] > 0.15 {
                    "≤ 150 ms after a reversal".into()
                } else {
                    "elsewhere".into()
                }
            }),
        ),
    ];
    let total: f64 = segs
        .iter()
        .filter_map(|s| s.r[ch].as_ref())
        .flat_map(|r| r.iter().map(|x| x * x))
        .sum();
    let mut out = Vec::new();
    for (name, label) in &splits {
        let mut acc: std::collections::BTreeMap<String, (usize, f64, f64)> = Default::default();
        for s in segs {
            let Some(r) = &s.r[ch] else { continue };
            for (i, ri) in r.iter().enumerate() {
                let e = acc.entry(label(s, i)).or_default();
                e.0 += 1;
                e.1 += ri;
                e.2 += ri * ri;
            }
        }
        for (region, (n, sum, ss)) in acc {
            out.push(RegionStat {
                split: name,
                region,
                samples: n,
                rms: (ss / n as f64).sqrt(),
                mean: sum / n as f64,
                energy_pct: if total > 0.0 { 100.0 * ss / total } else { 0.0 },
            });
        }
    }
    out
}

/// RMS residual on a signed-speed (7 bins) × stroke (5 bins) grid.
pub struct HeatMap {
    pub speed_edges: Vec<f64>,
    pub stroke_edges: Vec<f64>,
    /// [speed bin][stroke bin]: (rms, samples).
    pub cells: Vec<Vec<(f64, usize)>>,
}

pub fn heat_map(segs: &[&Segment], ch: usize) -> HeatMap {
    let vmax = segs
        .iter()
        .flat_map(|s| s.v.iter())
        .fold(1e-12f64, |m, v| m.max(v.abs()));
    let speed_edges: Vec<f64> = (0..=7)
        .map(|k| -vmax + 2.0 * vmax * k as f64 / 7.0)
        .collect();
    let (xlo, xhi) = segs
        .iter()
        .flat_map(|s| s.x.iter())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| {
            (l.min(*x), h.max(*x))
        });
    let stroke_edges: Vec<f64> = (0..=5)
        .map(|k| xlo + (xhi - xlo) * k as f64 / 5.0)
        .collect();
    let mut acc = vec![vec![(0.0, 0usize); 5]; 7];
    for s in segs {
        let Some(r) = &s.r[ch] else { continue };
        for (i, ri) in r.iter().enumerate() {
            let a = (((s.v[i] + vmax) / (2.0 * vmax) * 7.0) as usize).min(6);
            let b = if xhi > xlo {
                (((s.x[i] - xlo) / (xhi - xlo) * 5.0) as usize).min(4)
            } else {
                0
            };
            acc[a][b].0 += ri * ri;
            acc[a][b].1 += 1;
        }
    }
    let cells = acc
        .into_iter()
        .map(|row| {
            row.into_iter()
                .map(|(ss, n)| {
                    (
                        if n > 0 {
                            (ss / n as f64).sqrt()
                        } else {
                            f64::NAN
                        },
                        n,
                    )
                })
                .collect()
        })
        .collect();
    HeatMap {
        speed_edges,
        stroke_edges,
        cells,
    }
}
