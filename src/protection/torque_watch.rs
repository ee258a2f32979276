//! Torque-to-motion watch: from enable until the position loop first
//! settles, the rotor must go where its torque pushes it.
//!
//! Commutation checks the direction and the pole count with a small
//! rotation; an offset error it cannot see (a stored offset that is wrong,
//! a fit thrown off) turns the torque away from q. At 90° the motor makes
//! none and the load falls; beyond it the loops' correction drives the rod
//! further away. Either way the motor side leaves the command while the q
//! current the loops ask for pushes back towards it, which a working
//! commutation never allows by more than a release's sag (micrometres).
//! The reaction cannot rely on the angle: bridge off, the winding shorted
//! through the brake's engage time, the brake closed.
//!
//! While the brake still holds (the preload before it opens) the load
//! already rests on it: only a torque pointing the wrong way can twist the
//! rotor further along the load, so there the bound is the encoder's
//! resolution (two counts), and a heavy load, whose reversed preload twists
//! the disc by several counts, is caught before the brake ever opens.
//!
//! Rig-independent: the verdict is a sign and a distance, not a load or a
//! gain. A light payload and a heavy one both hold within the sag bar when
//! the commutation is right, and both leave the command when it is wrong.

use crate::params::ControlParams;

/// What one look found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TorqueWatchVerdict {
    /// Not watching, or nothing decided yet.
    Watching,
    /// The rotor left the command against the torque asked for it.
    Inconsistent,
    /// The position loop held the rod still at its command: the watch ends.
    Settled,
    /// Watched, the rod not moving on purpose, for
    /// `commutation.settle_timeout_s` without a settle.
    NeverSettled,
}

#[derive(Clone, Copy, Debug, Default)]
pub struct TorqueWatch {
    watching: bool,
    watched_s: f32,
    settled_s: f32,
}

impl TorqueWatch {
    pub const fn new() -> Self {
        Self { watching: false, watched_s: 0.0, settled_s: 0.0 }
    }

    /// Starts watching (the bridge has just been enabled).
    pub fn arm(&mut self) {
        *self = Self { watching: true, watched_s: 0.0, settled_s: 0.0 };
    }

    pub fn disarm(&mut self) {
        self.watching = false;
    }

    pub fn watching(&self) -> bool {
        self.watching
    }

    /// One position period: `following_error_m` is command − motor side,
    /// `q_current_reference_a` what the loops ask (positive drives the
    /// motor side positive), `speed_m_s` the motor side's speed.
    /// `brake_closed`: the preload builds against the closed brake.
    /// `may_settle`: the brake is open and the position loop holds alone
    /// (before that the brake holds the rod and a settle proves nothing).
    /// `moving`: a planned move runs; its following error is the loops'
    /// lag, not a verdict, so the watch waits for it to end.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        p: &ControlParams,
        following_error_m: f32,
        q_current_reference_a: f32,
        speed_m_s: f32,
        brake_closed: bool,
        may_settle: bool,
        moving: bool,
        dt_s: f32,
    ) -> TorqueWatchVerdict {
        if !self.watching {
            return TorqueWatchVerdict::Watching;
        }
        if moving {
            self.settled_s = 0.0;
            return TorqueWatchVerdict::Watching;
        }
        let open_travel = p.brake.torque_watch_travel_m;
        let travel = if brake_closed {
            2.0 * p.metres_per_rad() * (2.0 * core::f32::consts::PI) / p.encoder.counts_per_rev as f32
        } else {
            open_travel
        };
        // NaN compares false: no verdict from a non-finite input (those are
        // refused before this anyway).
        if following_error_m.abs() > travel && following_error_m * q_current_reference_a > 0.0 {
            self.watching = false;
            return TorqueWatchVerdict::Inconsistent;
        }
        let still_m_s = p.commutation.settle_speed_rad_s * p.metres_per_rad();
        if may_settle && following_error_m.abs() <= 0.5 * open_travel && speed_m_s.abs() < still_m_s {
            self.settled_s += dt_s;
        } else {
            self.settled_s = 0.0;
        }
        self.watched_s += dt_s;
        if self.settled_s >= p.commutation.settle_s {
            self.watching = false;
            return TorqueWatchVerdict::Settled;
        }
        if self.watched_s > p.commutation.settle_timeout_s {
            self.watching = false;
            return TorqueWatchVerdict::NeverSettled;
        }
        TorqueWatchVerdict::Watching
    }
}
