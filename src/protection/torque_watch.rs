//! Torque-to-motion watch: from enable until the position loop first
//! settles, the rotor must go where its torque pushes it.
//!
//! Commutation checks the direction and the pole count with a small
//! rotation; an offset error it cannot see (a stored offset that is wrong,
//! a fit thrown off) turns the torque away from q. At 90° the motor makes
//! none and the load falls; beyond it the loops' correction drives the rod
//! further away. Either way the motor side leaves its command while the q
//! current the loops ask for pushes back towards it, and keeps speeding
//! away: the push does not act (90°, the load's own fall) or adds to the
//! fall (180°).
//!
//! Leaving the command against the push alone is no proof: a release whose
//! preload fell short of the load (a hold current learnt while the brake
//! still carried part of it, a quick Disable/Enable) sags the rod past any
//! small bound before the loops catch it, with the current pushing back all
//! along. The difference is the trend. With the torque where q says, the
//! push grows with the error and turns the rod round within the speed
//! loop's response time, `J / (kp·K_t)`: the speed away stops growing.
//! With it turned away, more push brings no braking (90°) or more fall
//! (180°), so the speed away grows look after look. The verdict needs both:
//! beyond `brake.torque_watch_travel_m` against the push, and the speed
//! away grown without a break for longer than that response time. Once the
//! push exceeds the current the stated load needs
//! (`startup.expected_load_force_n`) by a quarter of the continuous current
//! (friction and the statement's error), a working motor decelerates the
//! rod at once: three looks of growth are then enough, which a reversed
//! torque, falling at up to (load + limit)/inertia, needs to be stopped
//! within the drop bound.
//!
//! While the brake still holds (the preload before it opens) the load
//! already rests on it and the rotor sits where the brake's twist put it,
//! which need not be the command (the load settled onto the brake after it
//! closed). The preload takes load off the brake, so with the torque where
//! q says the rotor untwists towards the push; only a torque pointing the
//! wrong way twists it further along the load. A rotor still settling onto
//! a brake that has just closed (an enable right after a fault or a
//! disable) moves along the load by itself, so the twist counts from where
//! it first rests. There the verdict is the rotor's motion since it rested
//! against the preload's push (the hold current's sign, not the loops'
//! answer to the reading), beyond the travel bound, with no trend asked;
//! a rotor once seen moving towards the push has shown the torque's sign
//! and is not judged there again. The bound is the travel, not the
//! encoder's resolution: a brake that does not hold yet leaves the loops to
//! catch the load with a small sag, and a reversed preload's twist (a few
//! counts) is caught anyway once the brake opens.
//!
//! With the brake open the verdict also says which of two errors it saw.
//! The speed away grows at the load's own rate over the inertia when the
//! torque is missing (an error near a quarter turn), and at the load's plus
//! the push's when it is reversed (near half a turn): the growth of the
//! verdict's look against the midpoint of the two tells them apart
//! ([`TorqueWatchVerdict::Reversed`]).
//!
//! Either error is an angle the drive can turn away, so the controller holds
//! the rod under control on a turned angle while the brake closes rather
//! than leaving the load to the short circuit, whose sink speed
//! `T R / (1.5 p² ψ²)` alone can drop a hot, heavy, weak-magnet unit beyond
//! the bound within the brake's engage time ([`TorqueWatch::turn`]). A
//! reversed torque is turned by half a turn. A missing torque says the error
//! is near a quarter turn but not which way (the torque left goes with the
//! cosine of the error, the same for either sign); the back-EMF's part
//! along d says which (its sine). The quarter turn it points to is tried,
//! watched with the same verdicts: tried the wrong way it reverses the
//! torque, and the watch sees the push add to the fall within two looks;
//! then the other quarter is half a turn further. A hold that fails
//! otherwise switches the bridge off with the winding shorted.
//!
//! Rig-independent: the verdict is a sign, a distance and a trend, not a
//! load or a gain; the time it allows follows the loop's own gains and the
//! inertia the drive is told.

use crate::params::ControlParams;

/// What one look found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TorqueWatchVerdict {
    /// Not watching, or nothing decided yet.
    Watching,
    /// The rotor left the command against the torque asked for it.
    Inconsistent,
    /// As `Inconsistent`, with the brake open, and the rotor sped away about
    /// as fast as the load and the push together drive it: the torque acts
    /// against q (an angle error near half a turn).
    Reversed,
    /// The position loop held the rod still at its command: the watch ends.
    Settled,
    /// Watched, the rod not moving on purpose, for
    /// `commutation.settle_timeout_s` without a settle.
    NeverSettled,
}

/// One look of the watch, at the position rate.
#[derive(Clone, Copy, Debug)]
pub struct TorqueLook {
    /// Command − motor side, metres.
    pub following_error_m: f32,
    /// The motor side, metres.
    pub position_m: f32,
    /// What the loops ask (positive drives the motor side positive).
    pub q_current_reference_a: f32,
    /// The hold current the preload builds towards (the push the drive
    /// means while the brake holds; the loops' own correction there answers
    /// the reading, which a faulty encoder can move at will).
    pub preload_current_a: f32,
    /// The motor side's speed, m/s.
    pub speed_m_s: f32,
    /// The q current the stated load needs, in the push's sign convention.
    pub stated_load_current_a: f32,
    /// The preload builds against the closed brake.
    pub brake_closed: bool,
    /// The brake is open and the position loop holds alone (before that the
    /// brake holds the rod and a settle proves nothing).
    pub may_settle: bool,
    /// A planned move runs: its following error is the loops' lag, not a
    /// verdict, so the watch waits for it to end.
    pub moving: bool,
    pub dt_s: f32,
}

/// How far the drive turned its angle away from the user's offset.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Turn {
    #[default]
    None,
    /// A quarter turn on trial after a missing torque.
    Quarter,
    /// Half a turn from where the torque was reversed (directly, or the
    /// quarter on trial reversed it): the last try.
    Final,
}

#[derive(Clone, Copy, Debug, Default)]
pub struct TorqueWatch {
    watched_s: f32,
    settled_s: f32,
    /// The speed leaving the command at the last look (m/s).
    away_m_s: f32,
    /// Where the rotor came to rest on the closed brake (m).
    start_m: f32,
    /// How long the speed away has grown without a break, against the
    /// push, beyond the travel bound.
    growing_s: f32,
    watching: bool,
    /// `start_m` is fixed: the rotor was found at rest on the brake.
    resting: bool,
    /// The rotor moved towards the preload's push on the closed brake.
    pushed_back: bool,
    /// The angle the drive holds on after a verdict (the controller's
    /// reaction).
    turn: Turn,
    /// The electrical offset before the turn, given back bit for bit.
    offset_before_rad: f32,
}

impl TorqueWatch {
    pub const fn new() -> Self {
        Self { watched_s: 0.0, settled_s: 0.0, away_m_s: 0.0, start_m: 0.0, growing_s: 0.0, watching: false, resting: false, pushed_back: false, turn: Turn::None, offset_before_rad: 0.0 }
    }

    /// The reaction to a verdict with the brake open: the angle offset to
    /// hold on next, watched again from now, or `None` when the angles are
    /// spent (the bridge goes off). `offset_rad` is the offset in use.
    ///
    /// A reversed torque turns by half a turn (exact for a half-turn error,
    /// within a quarter turn of q for any error beyond a quarter). A missing
    /// one turns by a quarter, the way the back-EMF points: with the angle
    /// `δ` off, the EMF `ω_e ψ` lies along the true q axis, so in the
    /// drive's frame its d part is `−ω_e ψ sin δ` (`emf_d_v`, the d voltage
    /// less `R i_d`): its sign against the speed's gives the error's. At
    /// the verdict the rotor turns at several rad/s, an EMF of tenths of a
    /// volt against millivolts of `ω_e L i_q` coupling. If the trial still
    /// went the wrong way the torque is now reversed, the next verdict says
    /// so, and half a turn on from the trial is the other quarter. Any other
    /// second verdict, and any verdict after a half turn, ends it.
    pub fn turn(&mut self, reversed: bool, offset_rad: f32, emf_d_v: f32, speed_rad_s: f32) -> Option<f32> {
        use core::f32::consts::{FRAC_PI_2, PI};
        let quarter_rad = if emf_d_v * speed_rad_s > 0.0 { -FRAC_PI_2 } else { FRAC_PI_2 };
        let (next, by_rad) = match (self.turn, reversed) {
            (Turn::None, true) => (Turn::Final, PI),
            (Turn::None, false) => (Turn::Quarter, quarter_rad),
            (Turn::Quarter, true) => (Turn::Final, PI),
            _ => return None,
        };
        let before = if self.turn == Turn::None { offset_rad } else { self.offset_before_rad };
        *self = Self { watching: true, turn: next, offset_before_rad: before, ..Self::new() };
        // Kept within ±π, as commutation leaves it.
        let o = offset_rad + by_rad;
        Some(if o > PI {
            o - 2.0 * PI
        } else if o < -PI {
            o + 2.0 * PI
        } else {
            o
        })
    }

    /// The drive holds on a turned angle.
    pub fn turned(&self) -> bool {
        self.turn != Turn::None
    }

    /// The hold on a turned angle is over (the bridge went off): the
    /// user's offset to put back, bit for bit.
    pub fn end_turn(&mut self) -> f32 {
        self.watching = false;
        self.turn = Turn::None;
        self.offset_before_rad
    }

    /// Starts watching (the bridge has just been enabled).
    pub fn arm(&mut self) {
        *self = Self { watching: true, ..Self::new() };
    }

    pub fn disarm(&mut self) {
        self.watching = false;
    }

    pub fn watching(&self) -> bool {
        self.watching
    }

    /// How long a working speed loop may let the speed away grow: its
    /// closed-loop time constant `J / (kp·K_t)` with the reflected inertia,
    /// twice (the current loop and the speed filter add their lag).
    pub fn response_s(p: &ControlParams) -> f32 {
        let gain = p.speed_pi.kp * p.torque_constant_n_m_a();
        // Validated gains and inertia are positive; a zero gain gives an
        // infinite allowance (no verdict), never a division by zero panic.
        2.0 * p.reflected_inertia_kg_m2() / gain
    }

    pub fn update(&mut self, p: &ControlParams, look: TorqueLook) -> TorqueWatchVerdict {
        if !self.watching {
            return TorqueWatchVerdict::Watching;
        }
        let e = look.following_error_m;
        let still_m_s = p.commutation.settle_speed_rad_s * p.metres_per_rad();
        // A rotor still settling onto a brake that just closed (an enable
        // right after a fault or a disable) moves along the load by itself:
        // the twist is measured from where it comes to rest.
        if look.brake_closed && !self.resting {
            self.start_m = look.position_m;
            self.resting = look.speed_m_s.abs() < still_m_s;
        }
        // A rotor seen moving towards the push has shown the torque's sign:
        // the preload untwisting the disc, or catching a load that was not
        // yet on the brake. The ringing that follows (a step of hold
        // current rings the rotor on the disc's compliance) swings it back
        // along the load and proves nothing.
        if look.brake_closed && look.speed_m_s * look.preload_current_a.signum() > still_m_s {
            self.pushed_back = true;
        }
        if look.moving {
            self.settled_s = 0.0;
            self.growing_s = 0.0;
            self.away_m_s = 0.0;
            return TorqueWatchVerdict::Watching;
        }
        // NaN compares false throughout: no verdict from a non-finite input
        // (those are refused before this anyway).
        let pushing_back = e * look.q_current_reference_a > 0.0;
        let away = if e > 0.0 { -look.speed_m_s } else { look.speed_m_s };
        let open_travel = p.brake.torque_watch_travel_m;
        if look.brake_closed {
            // The travel bound, not the encoder's resolution: a brake that
            // does not yet hold (still closing, or worn) leaves the loops to
            // catch the load with a small sag, as an enable does.
            let moved = look.position_m - self.start_m;
            if self.resting && !self.pushed_back && moved * look.preload_current_a < 0.0 && moved.abs() > open_travel {
                self.watching = false;
                return TorqueWatchVerdict::Inconsistent;
            }
        } else if pushing_back && e.abs() > open_travel && away > 0.0 && away > self.away_m_s {
            self.growing_s += look.dt_s;
            let push_a = if e > 0.0 { look.q_current_reference_a } else { -look.q_current_reference_a };
            let beyond_load = push_a - look.stated_load_current_a.abs() > 0.15 * p.thermal.continuous_current_a;
            // After a reversed torque the motion it built up (the drive
            // train's compliance, wound up by the push) may carry the motor
            // on for a while under a working torque: the loop's own
            // response time, no shortcut. A quarter on trial follows a
            // torque that was missing, not pushing: nothing is wound up, and
            // a wrong trial must be seen within looks.
            // A quarter on trial is judged early only on a reversal: the
            // rod already falls at the speed the missing torque let it reach,
            // and a right trial brakes it at once, a wrong one doubles its
            // growth. A trial that neither brakes nor reverses gets the
            // loop's full response time.
            let trial = self.turn == Turn::Quarter;
            let quick = (beyond_load || trial) && self.turn != Turn::Final;
            let allowed_s = if quick { 1.5 * look.dt_s } else { Self::response_s(p) };
            if self.growing_s > allowed_s {
                // How fast the speed away grew this look, against what the
                // stated load alone gives (no torque) and what it gives with
                // the push added to it (the torque reversed): the midpoint
                // tells the two apart.
                let growth_m_s2 = (away - self.away_m_s) / look.dt_s;
                let per_amp_m_s2 = p.torque_constant_n_m_a() / p.reflected_inertia_kg_m2() * p.metres_per_rad();
                let midpoint_m_s2 = per_amp_m_s2 * (look.stated_load_current_a.abs() + 0.5 * push_a);
                let reversed = growth_m_s2 > midpoint_m_s2;
                if reversed || !trial || self.growing_s > Self::response_s(p) {
                    self.watching = false;
                    return if reversed { TorqueWatchVerdict::Reversed } else { TorqueWatchVerdict::Inconsistent };
                }
            }
        } else {
            self.growing_s = 0.0;
        }
        self.away_m_s = away;
        // Held within half the travel for the whole settle time: the rod
        // stayed in a band of one travel, so its mean speed is below
        // travel / settle time. The speed estimate itself is not asked: a
        // rotor dithering by a count in a stiff friction band reads count
        // steps as speed spikes while the rod stands still.
        if look.may_settle && e.abs() <= 0.5 * open_travel {
            self.settled_s += look.dt_s;
        } else {
            self.settled_s = 0.0;
        }
        self.watched_s += look.dt_s;
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
