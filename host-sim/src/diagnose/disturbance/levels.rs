//! The levels of a piecewise-constant disturbance between change points,
//! cross-validated in time (alternate blocks of each interval predict
//! each other), per channel or as one force through the nominal model.

use super::Steps;
use crate::diagnose::effects::{Effect, MAXP};
use crate::diagnose::fit::ChannelPred;
use crate::diagnose::residual::{sg_smooth, Nominal, Segment, NCH, TORQUE};

/// One interval's level on one channel.
#[derive(Clone, Copy, Debug)]
pub struct LevelFit {
    pub channel: usize,
    pub start: usize,
    pub end: usize,
    pub level: f64,
    /// 1-sigma uncertainty (`None`: no weight).
    pub sd: Option<f64>,
}

/// Standard error of the mean of block levels.
fn spread(v: &[f64]) -> Option<f64> {
    if v.len() < 2 {
        return None;
    }
    let n = v.len() as f64;
    let mu = v.iter().sum::<f64>() / n;
    Some((v.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / (n - 1.0) / n).sqrt())
}

/// How the levels of an interval act on the channels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Levels {
    /// One level per channel and interval, each channel on its own.
    PerChannel,
    /// One force per interval acting through the nominal model on torque
    /// and position together: the load offset's regressors
    /// (`k (1 + μ sgn ω sgn F_nut)` on the torque, `−∂δ/∂F` on the
    /// position: the force winds the drive train up as it loads the
    /// motor). Physics nominal only.
    Force,
}

impl Levels {
    pub fn name(self) -> &'static str {
        match self {
            Levels::PerChannel => "per_channel",
            Levels::Force => "force",
        }
    }
}
/// The channels whose residual is Savitzky–Golay smoothed (the torque
/// channel: the current is smoothed, the accelerations differentiated
/// over ±m samples), so a step of the disturbance shows there as the
/// filter's step response: the prediction is smoothed alike. The position
/// channel (scale − encoder) is raw.
pub fn smoothed(c: usize) -> bool {
    c == TORQUE
}

/// Per-sample gain of the levels on channel `c` (1 per channel, or the
/// force's regressor).
fn gain(mode: Levels, s: &Segment, i: usize, c: usize, nominal: &Nominal) -> f64 {
    match mode {
        Levels::PerChannel => 1.0,
        Levels::Force => {
            let mut buf = [[0.0; NCH]; MAXP];
            Effect::LoadOffset.regressors(0.0, s, i, nominal, &mut buf);
            buf[0][c]
        }
    }
}

/// Cross-validated piecewise-constant prediction of the channels `chans`
/// of one segment. Every interval between change points is cut into
/// blocks of twice the smoothing window (halves, if shorter) of
/// alternating parity; the levels
/// of parity p (per channel, or one force for all channels) are fitted on
/// parity-p samples only and form a signal over the whole segment, which
/// predicts the samples of the other parity (smoothed where the channel's
/// residual is smoothed). Returns the prediction per channel, the levels
/// (channel, first sample, end, level on all of an interval's samples: N
/// for `Force`, the channel's own unit for `PerChannel`, and its 1-sigma
/// uncertainty) and every change point with the weighted residual energy
/// it explains. The uncertainty is the spread of the level over the
/// interval's blocks, over the root of their number: the floor is
/// correlated over about the smoothing window, which a per-sample
/// variance would not see, and the blocks are twice as long.
#[allow(clippy::too_many_arguments)]
pub fn cv_levels(
    s: &Segment,
    r: &[Option<Vec<f64>>; NCH],
    chans: &[usize],
    cps: &[usize],
    mode: Levels,
    nominal: &Nominal,
    w: &[f64; NCH],
) -> (ChannelPred, Vec<LevelFit>, Steps) {
    let n = s.len();
    let b = 2 * (2 * s.sg_m + 1);
    let mut bounds = vec![0];
    bounds.extend(cps.iter().copied().filter(|i| *i > 0 && *i < n));
    bounds.push(n);
    // An interval shorter than two blocks (edges may sit a smoothing
    // window apart) is cut in halves instead, so both parities hold data
    // and each half is still predicted by the other.
    let parity = |a: usize, e: usize, i: usize| ((i - a) / b.min(((e - a) / 2).max(1))) % 2;
    // Gains once per sample and channel.
    let g: Vec<Vec<f64>> = (0..NCH)
        .map(|c| {
            if chans.contains(&c) {
                (0..n).map(|i| gain(mode, s, i, c, nominal)).collect()
            } else {
                Vec::new()
            }
        })
        .collect();
    // Level signals per parity: per channel (PerChannel) or one force
    // (stored under every channel).
    let mut sig = [
        [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
        [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
    ];
    let mut levels = Vec::new();
    let mut steps = Vec::new();
    let mut last: Option<[(f64, f64); NCH]> = None;
    for iv in bounds.windows(2) {
        let (a, e) = (iv[0], iv[1]);
        // Normal equations per parity and per channel (summed for Force).
        let mut num = [[0.0; NCH]; 2];
        let mut den = [[0.0; NCH]; 2];
        let nb = (e - a).div_ceil(b);
        let mut bnum = vec![[0.0; NCH]; nb];
        let (mut sxx, mut sww) = ([0.0; NCH], [0.0; NCH]);
        let mut bden = vec![[0.0; NCH]; nb];
        for &c in chans {
            let Some(x) = &r[c] else { continue };
            let wc = if mode == Levels::Force { w[c] } else { 1.0 };
            for i in a..e {
                let p = parity(a, e, i);
                let ww = (wc * s.weight(c, i)).powi(2);
                num[p][c] += ww * g[c][i] * x[i];
                den[p][c] += ww * g[c][i] * g[c][i];
                bnum[(i - a) / b][c] += ww * g[c][i] * x[i];
                bden[(i - a) / b][c] += ww * g[c][i] * g[c][i];
                sxx[c] += ww * x[i] * x[i];
                sww[c] += ww;
            }
        }
        let lv = |p: usize, c: usize| match mode {
            Levels::PerChannel => {
                if den[p][c] > 0.0 {
                    num[p][c] / den[p][c]
                } else {
                    0.0
                }
            }
            Levels::Force => {
                let (nu, de): (f64, f64) = (num[p].iter().sum(), den[p].iter().sum());
                if de > 0.0 {
                    nu / de
                } else {
                    0.0
                }
            }
        };
        for (p, sp) in sig.iter_mut().enumerate() {
            for &c in chans {
                let l = lv(p, c);
                sp[c][a..e].iter_mut().for_each(|v| *v = l);
            }
        }
        // The interval's level on all its samples, per channel (the
        // data behind it: its weighted Σ g²), for the reported levels and
        // the change points' weight.
        let whole: [(f64, f64); NCH] = std::array::from_fn(|c| {
            let (nu, de) = match mode {
                Levels::PerChannel => (num[0][c] + num[1][c], den[0][c] + den[1][c]),
                Levels::Force => (
                    num[0].iter().chain(&num[1]).sum(),
                    den[0].iter().chain(&den[1]).sum(),
                ),
            };
            (if de > 0.0 { nu / de } else { 0.0 }, de)
        });
        if let Some(prev) = last.filter(|_| a > 0) {
            // Between-interval sum of squares: how much weighted residual
            // energy this change point explains (splitting the two
            // intervals against one level over both).
            let e: f64 = match mode {
                Levels::PerChannel => chans
                    .iter()
                    .map(|&c| {
                        let ((la, da), (lb, db)) = (prev[c], whole[c]);
                        if da + db > 0.0 {
                            w[c] * w[c] * da * db / (da + db) * (la - lb).powi(2)
                        } else {
                            0.0
                        }
                    })
                    .sum(),
                Levels::Force => chans.first().map_or(0.0, |&c| {
                    let ((la, da), (lb, db)) = (prev[c], whole[c]);
                    if da + db > 0.0 {
                        da * db / (da + db) * (la - lb).powi(2)
                    } else {
                        0.0
                    }
                }),
            };
            steps.push((a, e));
        }
        last = Some(whole);
        // Every channel's level (one force under each channel for `Force`).
        for &c in chans {
            if whole[c].1 > 0.0 {
                let block: Vec<f64> = (0..nb)
                    .filter_map(|q| {
                        let (nu, de): (f64, f64) = match mode {
                            Levels::PerChannel => (bnum[q][c], bden[q][c]),
                            Levels::Force => (bnum[q].iter().sum(), bden[q].iter().sum()),
                        };
                        (de > 0.0).then(|| nu / de)
                    })
                    .collect();
                // Too short for two blocks: the residual's variance per
                // sample taken as correlated over the smoothing window.
                let short = || {
                    let (xx, ww, de): (f64, f64, f64) = match mode {
                        Levels::PerChannel => (sxx[c], sww[c], whole[c].1),
                        Levels::Force => (sxx.iter().sum(), sww.iter().sum(), whole[c].1),
                    };
                    let var = ((xx - whole[c].0 * whole[c].0 * de) / ww).max(0.0);
                    (ww > 0.0 && de > 0.0).then(|| (var * (2 * s.sg_m + 1) as f64 / de).sqrt())
                };
                levels.push(LevelFit { channel: c, start: a, end: e, level: whole[c].0, sd: spread(&block).or_else(short) });
            }
        }
    }
    let pred = std::array::from_fn(|c| {
        let x = r[c].as_ref()?;
        if !chans.contains(&c) {
            return Some(vec![0.0; x.len()]);
        }
        let sm: [Vec<f64>; 2] = std::array::from_fn(|p| {
            let v: Vec<f64> = (0..n).map(|i| g[c][i] * sig[p][c][i]).collect();
            if smoothed(c) {
                sg_smooth(&v, s.sg_m)
            } else {
                v
            }
        });
        // Which interval (and so which parity origin) each sample is in.
        let mut out = vec![0.0; n];
        for iv in bounds.windows(2) {
            for (i, o) in out.iter_mut().enumerate().take(iv[1]).skip(iv[0]) {
                *o = sm[1 - parity(iv[0], iv[1], i)][i];
            }
        }
        Some(out)
    });
    (pred, levels, steps)
}
