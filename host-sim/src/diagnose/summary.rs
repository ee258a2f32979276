//! The diagnosis summary (`summary.json`) and its parts. Each shrink
//! figure has one definition (`Figures`), used in the verdict, the tables
//! and the JSON alike.

use super::log::Issue;
use super::{disturbance, events, gates, replay, verdict};
use super::{regions, spectrum};
use std::collections::BTreeMap;

#[derive(Clone, Debug, serde::Serialize)]
pub struct RankEntry {
    pub effect: String,
    pub description: String,
    pub params: BTreeMap<String, f64>,
    /// Weighted shrink (`figures::WEIGHTED`): held-out gap over all
    /// channels, each weighted by 1/RMS of its training nominal residual
    /// (the ranking score), %.
    pub weighted_shrink_pct: f64,
    /// Primary-channel shrink (`figures::PRIMARY`): held-out RMS shrink of
    /// the summary's primary channel, %.
    pub primary_shrink_pct: f64,
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
    /// Primary-channel shrink with the top effect, % (`figures::PRIMARY`).
    pub gap_shrink_pct: f64,
    /// Weighted shrink with the top effect, % (`figures::WEIGHTED`).
    pub gap_shrink_weighted_pct: f64,
    pub stack: Vec<String>,
    pub stack_params: BTreeMap<String, f64>,
    pub heldout_fit_after_stack: f64,
    pub gap_shrink_stack_pct: f64,
    pub gap_shrink_stack_weighted_pct: f64,
    /// The top effect refitted on each half of the training run: its
    /// held-out primary-channel shrink with each, and the change of its
    /// leading parameter between them relative to its value (a drift check).
    pub top_halves_primary_shrink_pct: Option<(f64, f64, f64)>,
    /// The definition of every figure above, by label.
    pub figure_definitions: BTreeMap<String, String>,
    /// Sanity gates, reported before any finding.
    pub gates: Vec<gates::Gate>,
    /// Time structure of the held-out remainder (after the stack), per channel.
    pub time_structure: Vec<events::TimeStructure>,
    /// The disturbance effect (unmeasured force / input disturbance as a signal).
    pub disturbance: Option<disturbance::DisturbanceFit>,
    /// The nominal's own parameters re-fitted on training, scored on the
    /// held-out part: the rig-mismatch explanation.
    pub refit: Option<super::refit::Refit>,
    /// The disturbance fitted on what the re-fit leaves.
    pub refit_disturbance: Option<disturbance::DisturbanceFit>,
    /// Generic structures fitted on what the stack leaves of the primary
    /// channel, best first.
    pub generic: Vec<super::generic::GenericFit>,
    /// The open-world verdict.
    pub verdict: verdict::Verdict,
    pub wall_s: f64,
    /// Closed-loop replay (with `--replay`).
    pub replay: Option<replay::Replay>,
}
