//! How the baseline gates govern the verdict: a nominal unsound on what it
//! was fitted on breaks it; implausible library fits block library causes
//! unless the stack accounts for them.

use super::super::gates::{Gate, NOMINAL_FIT_MIN_PCT};
use super::super::residual::{CHANNELS, NCH};

/// How the baseline gates govern the verdict.
pub(super) enum Baseline<'a> {
    /// No gate against the baseline.
    Sound,
    /// The rig's physics does not fit: no cause of any kind is named.
    Broken(Vec<&'a Gate>),
    /// The library contorts itself (`implausible_fits`): no library cause;
    /// a disturbance (something outside the rig's description) may be.
    NoLibraryCause(&'a Gate),
}

/// Only a nominal unsound on what it was fitted on (`gates::baseline_broken`)
/// breaks the baseline; a poor fit of the diagnosed log is the gap itself
/// (noted when the stack accounts for it).
/// `implausible_fits` blocks library causes unless the stack accounts for
/// it too: refitted on what the stack leaves, fewer than
/// `IMPLAUSIBLE_FITS_MISMATCH` effects stay implausible.
pub(super) fn baseline<'a>(
    gates: &'a [Gate],
    stack_train_fit: &[Option<f64>; NCH],
    implausible_after_stack: Option<&Vec<String>>,
) -> (Baseline<'a>, String) {
    let mut broken = Vec::new();
    let mut notes = Vec::new();
    for g in gates {
        if super::super::gates::baseline_broken(g) {
            broken.push(g);
        } else if g.kind == "nominal_poor_fit" {
            let c = CHANNELS
                .iter()
                .position(|c| Some(*c) == g.channel.as_deref())
                .unwrap_or(0);
            match stack_train_fit[c] {
                Some(f) if f >= NOMINAL_FIT_MIN_PCT[c] => notes.push(format!(
                    "The nominal fits the {} channel poorly (training Fit {:.1} %), but with the library stack it reaches {f:.1} %: the stack accounts for the poor fit. ",
                    CHANNELS[c], g.figure
                )),
                // The diagnosed log's own fit is the size of the gap, not
                // a verdict on the nominal: the explanations weigh it.
                _ => {}
            }
        }
    }
    let note = notes.concat();
    if !broken.is_empty() {
        return (Baseline::Broken(broken), note);
    }
    match gates.iter().find(|g| g.kind == "implausible_fits") {
        Some(g) => match implausible_after_stack {
            Some(still) if still.len() < super::super::gates::IMPLAUSIBLE_FITS_MISMATCH => (
                Baseline::Sound,
                format!(
                    "{} library effects fit implausibly against the nominal, but refitted on what the stack leaves {}: the stack accounts for them. {note}",
                    g.figure,
                    if still.is_empty() { "none does".to_string() } else { format!("only {} does", still.join(", ")) }
                ),
            ),
            _ => (Baseline::NoLibraryCause(g), note),
        },
        None => (Baseline::Sound, note),
    }
}

