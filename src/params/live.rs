//! Which parameters may change while the bridge is on.
//!
//! Live (applied between two periods, the loops keep their states, gains
//! bumplessly): the loop gains, the torque filter, the trajectory and
//! stream limits, the compensation's bounds, the current, power and speed
//! limits and the modulation depth, the feedforward model (inertia, mass,
//! friction) and the load-estimate filter.
//!
//! Bridge off only: what the loops' structure, the position frame or the
//! protection rests on: rates, motor, screw lead, encoder, stroke, fault
//! thresholds, brake, thermal model, ratings, the start-up steps and the
//! power stage. Changing these under a turning motor would move the frame
//! the rod is held in or a trip threshold mid-motion.

use super::leaves::{self, LEAF_COUNT};
use super::ControlParams;

/// Path prefixes of the parameters that change live (a trailing `.` is a
/// whole group).
const LIVE: &[&str] = &[
    "control.current_pi.",
    "control.speed_pi.",
    "control.torque_filter_hz",
    "control.position_kp_per_s",
    "control.trajectory.",
    "control.stream.",
    "control.compensation.",
    "control.limits.current_max_a",
    "control.limits.copper_power_max_w",
    "control.limits.speed_max_rad_s",
    "control.limits.max_modulation",
    "control.drive_train.screw_efficiency",
    "control.drive_train.rotating_inertia_kg_m2",
    "control.drive_train.moving_mass_kg",
    "control.drive_train.viscous_friction_n_m_s_rad",
    "control.drive_train.coulomb_friction_n_m",
    "control.drive_train.friction_feedforward_speed_rad_s",
    "control.drive_train.friction_feedforward_gain",
    "control.load_estimate.",
];

/// `path` starts with `prefix` (`str::starts_with` is not `const`).
const fn starts_with(path: &[u8], prefix: &[u8]) -> bool {
    if prefix.len() > path.len() {
        return false;
    }
    let (mut p, mut q) = (path, prefix);
    while let ([a, pt @ ..], [b, qt @ ..]) = (p, q) {
        if *a != *b {
            return false;
        }
        p = pt;
        q = qt;
    }
    true
}

/// [`ControlParams::is_live_path`] as a `const fn`.
const fn live(path: &str) -> bool {
    let path = path.as_bytes();
    let mut rest = LIVE;
    while let [p, tail @ ..] = rest {
        let p = p.as_bytes();
        let group = matches!(p, [.., b'.']);
        if starts_with(path, p) && (group || path.len() == p.len()) {
            return true;
        }
        rest = tail;
    }
    false
}

/// Bit `i`: leaf `i` changes live. Worked out from the paths when the
/// image is built, so the drive compares leaves through the table and
/// holds neither the paths nor a field-by-field comparison.
const LIVE_LEAVES: u128 = {
    let mut mask = 0u128;
    let mut i = 0;
    while i < LEAF_COUNT {
        if live(leaves::path(i)) {
            mask |= 1 << i;
        }
        i += 1;
    }
    mask
};
const _: () = assert!(LEAF_COUNT <= 128);

/// How many leaves change with the bridge off only.
const STRUCTURAL_COUNT: usize = LEAF_COUNT - LIVE_LEAVES.count_ones() as usize;

/// Their indices, in leaf order: `bridge_off_change` walks this list instead
/// of testing a 128-bit mask per leaf (the PWM interrupt runs it when it
/// applies a set; the mask walk cost ≈ 7 000 instructions, longer than a
/// PWM period).
// Evaluated when the image is built: an index out of range there fails the
// build; nothing here runs on the drive.
#[allow(clippy::indexing_slicing)]
const STRUCTURAL: [u8; STRUCTURAL_COUNT] = {
    let mut list = [0u8; STRUCTURAL_COUNT];
    let (mut i, mut n) = (0, 0);
    while i < LEAF_COUNT {
        if LIVE_LEAVES & (1 << i) == 0 {
            list[n] = i as u8;
            n += 1;
        }
        i += 1;
    }
    list
};

impl ControlParams {
    /// True if the parameter at `path` may change with the bridge on.
    pub fn is_live_path(path: &str) -> bool {
        LIVE.iter().any(|p| if p.ends_with('.') { path.starts_with(p) } else { path == *p })
    }

    /// The first leaf (index, `params::leaves`) that differs between
    /// `self` and `new` and changes only with the bridge off; `None` if
    /// every difference is live. The same split as
    /// [`ControlParams::is_live_path`] (a test walks every leaf).
    pub fn bridge_off_change(&self, new: &Self) -> Option<u16> {
        STRUCTURAL.iter().find(|&&i| !leaves::same(self, new, usize::from(i))).map(|&i| u16::from(i))
    }
}
