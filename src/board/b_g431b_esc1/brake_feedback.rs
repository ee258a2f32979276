//! The brake feedback's verdict, period by period: how long the feedback
//! may disagree with the release signal before the drive calls the brake
//! failed. Free of the HAL, so firmware-tests runs it as the board does.

/// How long the feedback may disagree with the command before the
/// `BRAKE_FEEDBACK` fault latches: twice the slowest of a typical spring
/// brake's release and engage times (≤ 50 ms), in PWM periods at 20 kHz.
pub const FEEDBACK_TIMEOUT_PERIODS: u32 = 2_000;

/// Counts how long the feedback has disagreed with the command.
#[derive(Debug, Default)]
pub struct FeedbackWatch {
    disagree_periods: u32,
}

/// What the watch saw this period.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum FeedbackVerdict {
    Agrees,
    /// Disagreeing, not yet for long.
    Settling,
    /// Disagreeing for longer than [`FEEDBACK_TIMEOUT_PERIODS`].
    Disagrees,
}

impl FeedbackWatch {
    pub const fn new() -> Self {
        Self { disagree_periods: 0 }
    }

    /// One period: `commanded_release` against `released` (the feedback).
    #[inline(always)]
    pub fn update(&mut self, commanded_release: bool, released: bool) -> FeedbackVerdict {
        if commanded_release == released {
            self.disagree_periods = 0;
            return FeedbackVerdict::Agrees;
        }
        self.disagree_periods = self.disagree_periods.saturating_add(1);
        if self.disagree_periods > FEEDBACK_TIMEOUT_PERIODS {
            FeedbackVerdict::Disagrees
        } else {
            FeedbackVerdict::Settling
        }
    }
}
