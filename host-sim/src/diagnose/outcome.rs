//! What a diagnosis returns besides its summary: the nominal, the
//! segments, the fitted top effect and stack, and the disturbance's
//! held-out prediction, with the views the report takes of them.

use super::fit::{self, Term};
use super::residual::{Nominal, Segment};
use super::summary::Summary;
use super::events;

/// Everything the report needs besides the summary.
pub struct Diagnosis {
    pub summary: Summary,
    pub nominal: Nominal,
    pub segments: Vec<Segment>,
    pub primary: usize,
    /// Top-effect and stack terms with their parameters.
    pub top: Option<(Vec<Term>, Vec<f64>)>,
    pub stack: Option<(Vec<Term>, Vec<f64>)>,
    /// The disturbance's cross-validated prediction of the held-out
    /// remainder (per held-out segment), and its change points.
    pub disturbance_heldout: events::Remainder,
    pub change_points: Vec<Vec<usize>>,
}

impl Diagnosis {
    pub fn train(&self) -> Vec<&Segment> {
        self.segments.iter().filter(|s| !s.heldout).collect()
    }
    pub fn heldout(&self) -> Vec<&Segment> {
        self.segments.iter().filter(|s| s.heldout).collect()
    }
    /// The held-out residual after the stack (what the time-structure
    /// analyses see), per held-out segment.
    pub fn heldout_remainder(&self) -> events::Remainder {
        self.heldout()
            .iter()
            .map(|s| {
                let p = self
                    .stack
                    .as_ref()
                    .map(|(t, q)| fit::predict(t, q, s, &self.nominal));
                std::array::from_fn(|c| {
                    let r = s.r[c].as_ref()?;
                    let pc = p.as_ref().and_then(|p| p[c].as_ref());
                    Some(
                        r.iter()
                            .enumerate()
                            .map(|(i, v)| v - pc.map_or(0.0, |q| q[i]))
                            .collect(),
                    )
                })
            })
            .collect()
    }
}

