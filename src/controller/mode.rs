//! The mode machine: every change of the drive's mode goes through
//! [`Controller::set_mode`], which takes only the transitions listed in
//! [`TRANSITIONS`]. Staying in a mode is always allowed (no change).
//!
//! The table is the whole story of what the drive may do next; a test walks
//! it (every row reachable from the commands and faults, nothing else ever
//! taken).

use super::Controller;
use crate::telemetry::Mode;

/// Every mode, in `Mode`'s order (the index of a transition's bit).
pub const MODES: [Mode; 9] = [
    Mode::Disabled,
    Mode::Calibrating,
    Mode::Aligning,
    Mode::Homing,
    Mode::Running,
    Mode::Stopping,
    Mode::Fault,
    Mode::Braking,
    Mode::Preloading,
];

/// The allowed changes of mode, `(from, to)`.
pub const TRANSITIONS: [(Mode, Mode); 32] = [
    // Start-up steps (`Calibrate`, `Align`, `Home`, `StartUp`).
    (Mode::Disabled, Mode::Calibrating),
    (Mode::Calibrating, Mode::Disabled),
    (Mode::Disabled, Mode::Aligning),
    (Mode::Aligning, Mode::Running),
    (Mode::Running, Mode::Homing),
    (Mode::Preloading, Mode::Homing),
    (Mode::Homing, Mode::Running),
    // `Enable`: with a brake, the hold current builds first.
    (Mode::Disabled, Mode::Preloading),
    (Mode::Disabled, Mode::Running),
    (Mode::Preloading, Mode::Running),
    (Mode::Braking, Mode::Running),
    // `Disable`: with a brake, stop and let it close under the loops.
    (Mode::Running, Mode::Braking),
    (Mode::Homing, Mode::Braking),
    (Mode::Preloading, Mode::Braking),
    (Mode::Stopping, Mode::Braking),
    (Mode::Braking, Mode::Disabled),
    (Mode::Braking, Mode::Fault),
    // `Disable` without a brake (or before the bridge was on).
    (Mode::Calibrating, Mode::Disabled),
    (Mode::Running, Mode::Disabled),
    (Mode::Homing, Mode::Disabled),
    // A controlled-stop fault.
    (Mode::Running, Mode::Stopping),
    (Mode::Homing, Mode::Stopping),
    (Mode::Preloading, Mode::Stopping),
    // A bridge-off fault, from wherever the drive is.
    (Mode::Disabled, Mode::Fault),
    (Mode::Calibrating, Mode::Fault),
    (Mode::Aligning, Mode::Fault),
    (Mode::Homing, Mode::Fault),
    (Mode::Running, Mode::Fault),
    (Mode::Stopping, Mode::Fault),
    (Mode::Preloading, Mode::Fault),
    // `ClearFaults`: back to idle, or on from where a controlled stop held.
    (Mode::Fault, Mode::Disabled),
    (Mode::Stopping, Mode::Running),
];

/// Bit of `from → to` in [`Controller::transitions_taken`].
pub const fn transition_bit(from: Mode, to: Mode) -> u128 {
    // 9 × 8 + 8 = 80 < 128: no overflow; wrapping_shl says so to the lints.
    let index = (from as u32).wrapping_mul(MODES.len() as u32).wrapping_add(to as u32);
    1u128.wrapping_shl(index)
}

/// The table as one mask of [`transition_bit`]s (built at compile time).
const ALLOWED: u128 = {
    let mut mask = 0u128;
    let mut rest: &[(Mode, Mode)] = &TRANSITIONS;
    while let [(from, to), tail @ ..] = rest {
        mask |= transition_bit(*from, *to);
        rest = tail;
    }
    mask
};

/// Whether the mode machine takes `from → to`.
pub const fn allowed(from: Mode, to: Mode) -> bool {
    from as u8 == to as u8 || ALLOWED & transition_bit(from, to) != 0
}

impl Controller {
    /// The one place the mode changes. A change the table does not list is
    /// refused: the mode stays, and the attempt is recorded in
    /// [`Controller::transitions_refused`] (a caller asking for it is a bug
    /// the mode machine's test looks for).
    pub(super) fn set_mode(&mut self, to: Mode) {
        let from = self.mode;
        if from == to {
            return;
        }
        let bit = transition_bit(from, to);
        if allowed(from, to) {
            self.transitions_taken |= bit;
            self.mode = to;
        } else {
            self.transitions_refused |= bit;
        }
    }

    /// Every mode transition taken since creation, one
    /// [`transition_bit`] each: a record of where the drive has been.
    pub fn transitions_taken(&self) -> u128 {
        self.transitions_taken
    }

    /// Every transition asked for that the table does not allow.
    pub fn transitions_refused(&self) -> u128 {
        self.transitions_refused
    }
}
