//! Golden vectors: the inputs `golden-gen` recorded on the host go through
//! the target build of the very same code, and the outputs must agree with
//! the host's within each column's stated tolerance (see the `golden` crate
//! for the families, the tolerances and why they are what they are).
//!
//! Each test prints how many values were bit-identical and the largest
//! difference in ulps, so a drift inside the tolerance is visible too.
#![no_std]
#![no_main]

use firmware_tests::{check, test_main, Outcome};
use golden::{agrees, ulps, ClosedLoop, Family, Foc, Observer, Observer5, Table, Trajectory};

const FOC: &[u8] = include_bytes!("../golden/data/foc.bin");
const TRAJECTORY: &[u8] = include_bytes!("../golden/data/trajectory.bin");
const CLOSED_LOOP: &[u8] = include_bytes!("../golden/data/closed_loop.bin");
const OBSERVER: &[u8] = include_bytes!("../golden/data/observer.bin");
const OBSERVER5: &[u8] = include_bytes!("../golden/data/observer5.bin");

fn replay<F: Family>(bytes: &[u8]) -> Outcome {
    let table = match Table::parse(bytes) {
        Ok(t) => t,
        Err(e) => {
            firmware_tests::report(
                file!(),
                line!(),
                "Table::parse",
                format_args!("{}.bin: {}", F::NAME, e),
            );
            return Err(firmware_tests::Failed);
        }
    };
    let cols = F::COLUMNS;
    check!(
        table.family == F::ID,
        "{}.bin holds family {}",
        F::NAME,
        table.family
    );
    check!(
        table.in_words == F::IN_WORDS && table.out_words == cols.len(),
        "{}.bin is {}+{} words wide, the code {}+{}: regenerate (cd firmware-tests/golden-gen && cargo run --release)",
        F::NAME,
        table.in_words,
        table.out_words,
        F::IN_WORDS,
        cols.len()
    );
    let mut fam = F::new();
    let mut input = [0u32; 16];
    let mut out = [0u32; 16];
    let mut identical = 0usize;
    let mut max_ulps = [0u32; 16];
    for row in 0..table.rows {
        for (c, x) in input[..F::IN_WORDS].iter_mut().enumerate() {
            *x = table.input(row, c);
        }
        fam.eval(row, &input[..F::IN_WORDS], &mut out[..cols.len()]);
        for (c, col) in cols.iter().enumerate() {
            let (host, target) = (table.output(row, c), out[c]);
            if host == target {
                identical += 1;
            } else if col.float {
                max_ulps[c] = max_ulps[c].max(ulps(host, target));
            }
            if !agrees(col, host, target) {
                firmware_tests::report(
                    file!(),
                    line!(),
                    "target agrees with host",
                    format_args!(
                        "{} row {} column {}: host {:#010x} ({:e}), target {:#010x} ({:e}), {} ulp, tolerance {:?}",
                        F::NAME,
                        row,
                        col.name,
                        host,
                        f32::from_bits(host),
                        target,
                        f32::from_bits(target),
                        ulps(host, target),
                        col.tol
                    ),
                );
                return Err(firmware_tests::Failed);
            }
        }
    }
    let values = table.rows * cols.len();
    let worst = max_ulps[..cols.len()].iter().copied().max().unwrap_or(0);
    firmware_tests::note(format_args!(
        "{}: {} rows, {} values, {} bit-identical, max {} ulp ({})",
        F::NAME,
        table.rows,
        values,
        identical,
        worst,
        F::WHY
    ));
    Ok(())
}

/// FOC step outputs over 64 angles × 5 current amplitudes (with references,
/// speeds, buses and raw angles up to ±1000 rad cycled through).
fn foc_step_matches_host() -> Outcome {
    replay::<Foc>(FOC)
}

/// S-curve samples of 8 moves (both directions, cruising, short, tiny, none).
fn trajectory_matches_host() -> Outcome {
    replay::<Trajectory>(TRAJECTORY)
}

/// 5000 periods of `Controller::step` on a sensor sequence recorded in
/// closed loop on the host: duties, enable, faults, mode, speed, position.
fn closed_loop_duties_match_host() -> Outcome {
    replay::<ClosedLoop>(CLOSED_LOOP)
}

/// The error observer over a 6^4 grid around its trained range, and a NaN.
fn observer_matches_host() -> Outcome {
    replay::<Observer>(OBSERVER)
}

/// The drive's five-slot network: a five-input model compiled in and the
/// same words uploaded in chunks and read back from the flash record, over
/// a 4^4 grid × 4 directions of travel and two NaN rows; and the compiled
/// four-input model in the five slots against itself alone.
fn observer5_matches_host() -> Outcome {
    replay::<Observer5>(OBSERVER5)
}

test_main!(
    foc_step_matches_host,
    trajectory_matches_host,
    closed_loop_duties_match_host,
    observer_matches_host,
    observer5_matches_host,
);
