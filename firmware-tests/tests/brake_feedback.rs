//! The brake feedback's verdict as the PWM interrupt computes it
//! (`src/board/b_g431b_esc1/brake_feedback.rs`, included by path): a
//! disagreement with the release signal is tolerated for the brake's move
//! time and no longer; agreement resets the count at once.
#![no_std]
#![no_main]

use firmware_tests::{check, test_main, Outcome};

#[path = "../../src/board/b_g431b_esc1/brake_feedback.rs"]
mod brake_feedback;
use brake_feedback::{FeedbackVerdict as V, FeedbackWatch, FEEDBACK_TIMEOUT_PERIODS as T};

/// Released while commanded closed: settling for exactly the timeout, then
/// a fault every period until the feedback agrees.
fn disagreement_latches_after_the_timeout() -> Outcome {
    let mut w = FeedbackWatch::new();
    check!(w.update(false, false) == V::Agrees);
    for k in 1..=T {
        let v = w.update(false, true);
        check!(v == V::Settling, "period {}: not settling", k);
    }
    check!(w.update(false, true) == V::Disagrees, "no fault after {} periods", T + 1);
    check!(w.update(false, true) == V::Disagrees);
    check!(w.update(false, false) == V::Agrees, "agreement does not clear");
    Ok(())
}

/// The brake's own move after a command change (released later than
/// asked, closed later than asked) is not a fault, however often it
/// happens; the count restarts with each agreement.
fn brake_moves_within_the_timeout_are_no_fault() -> Outcome {
    let mut w = FeedbackWatch::new();
    for _ in 0..50 {
        for _ in 0..T / 2 {
            check!(w.update(true, false) == V::Settling);
        }
        check!(w.update(true, true) == V::Agrees);
        for _ in 0..T {
            check!(w.update(false, true) == V::Settling);
        }
        check!(w.update(false, false) == V::Agrees);
    }
    // Commanded release, the brake never opens: a fault.
    for _ in 0..T {
        check!(w.update(true, false) == V::Settling);
    }
    check!(w.update(true, false) == V::Disagrees);
    Ok(())
}

test_main!(disagreement_latches_after_the_timeout, brake_moves_within_the_timeout_are_no_fault);
