//! Latched faults. A fault switches the bridge off at once and stays set until
//! an explicit clear command finds its cause gone (ODrive/MCSDK habit: the
//! operator acknowledges, the drive never re-arms by itself).

/// A set of fault bits (`bitflags`: the set operations; one list below gives
/// each bit, its constant and its short name).
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
#[serde(transparent)]
pub struct FaultSet(u32);

/// Declares every fault once: its bit, its constant (with the doc) and the
/// short name logs and reports use.
macro_rules! faults {
    ($($(#[doc = $doc:literal])* $bit:ident = $n:literal => $name:ident,)*) => {
        bitflags::bitflags! {
            impl FaultSet: u32 {
                $($(#[doc = $doc])* const $bit = 1 << $n;)*
            }
        }

        impl FaultSet {
            /// Every fault, in bit order, with a short name for logs and reports.
            pub const ALL: [(Self, &'static str); [$($n),*].len()] = [$((Self::$bit, stringify!($name)),)*];
        }
    };
}

faults! {
    /// Instantaneous |i_phase| above `faults.overcurrent_trip_a`.
    OVERCURRENT = 0 => overcurrent,
    BUS_OVERVOLTAGE = 1 => bus_overvoltage,
    /// Only while the bridge is enabled: a board powered from USB with the
    /// bus off must still be configurable.
    BUS_UNDERVOLTAGE = 2 => bus_undervoltage,
    /// The encoder moved further in one period than the motor can.
    ENCODER_JUMP = 3 => encoder_jump,
    /// |position command − motor-side position| above the threshold.
    POSITION_FOLLOWING = 4 => position_following,
    /// Motor-side position beyond the stroke plus the allowed overtravel.
    STROKE_OVERTRAVEL = 5 => stroke_overtravel,
    /// NaN or infinity in a sensor sample.
    NON_FINITE_INPUT = 6 => non_finite_input,
    /// The parameter set failed validation; the bridge never enables.
    INVALID_PARAMS = 7 => invalid_params,
    /// A new sample arrived before the previous step finished (board-reported).
    ISR_OVERRUN = 8 => isr_overrun,
    /// The I²t winding model passed its trip level.
    MOTOR_OVERTEMP = 9 => motor_overtemp,
    /// |ω_ref − ω| stayed above the threshold.
    SPEED_FOLLOWING = 10 => speed_following,
    /// No encoder count while commanded to turn: lost signal or stalled rotor.
    ENCODER_LOST = 11 => encoder_lost,
    /// The motor would not stop inside the stroke (soft limit).
    SOFT_LIMIT = 12 => soft_limit,
    /// The error observer's shift was non-finite or beyond its bound.
    OBSERVER_OUT_OF_BOUNDS = 13 => observer_out_of_bounds,
    /// The last reset came from the independent watchdog (board-reported).
    WATCHDOG_RESET = 14 => watchdog_reset,
    /// The three phase currents do not sum to zero: a stuck, offset or
    /// open-circuit current sensor (a star-connected motor has no path for a
    /// common-mode current).
    CURRENT_SENSOR = 15 => current_sensor,
    /// One phase carries no current while the reference needs it there: a
    /// broken motor lead or a dead inverter leg. The phase currents still
    /// sum to zero (the other two carry ±the same), so `CURRENT_SENSOR`
    /// cannot see it.
    OPEN_PHASE = 16 => open_phase,
    /// The board's comparator break switched the outputs off in hardware
    /// (board-reported): the core must not carry on as if it were driving.
    BRIDGE_BREAK = 17 => bridge_break,
    /// A controlled stop could not hold the motion: the rod left the stop's
    /// path by more than `faults.stop_following_error_m` while the motor's
    /// present current limit gives less torque than the brake holds.
    /// Escalates to the bridge off with the holding brake engaged.
    STOP_FAILED = 18 => stop_failed,
    /// Current-offset calibration: an offset or the noise beyond its bound,
    /// or the bus moved during the average (a sagging supply).
    CALIBRATION_FAILED = 19 => calibration_failed,
    /// Commutation: the brake-held rotor showed no twist under the test
    /// torque (encoder unplugged, or no signal).
    ENCODER_NO_SIGNAL = 20 => encoder_no_signal,
    /// The brake let the shaft turn further than its disc can twist: it
    /// slipped under the commutation test torque or the load alone.
    BRAKE_SLIP = 21 => brake_slip,
    /// The check rotation went the other way: encoder direction or phase
    /// order reversed. Also, from enable until the loops first hold the rod
    /// still, the motor side left its command against the torque asked of
    /// it (`brake.torque_watch_travel_m`): a commutation offset error.
    WRONG_DIRECTION = 22 => wrong_direction,
    /// The check rotation's size disagrees with `motor.pole_pairs`.
    WRONG_POLE_PAIRS = 23 => wrong_pole_pairs,
    /// The rotor did not follow the check rotation: blocked.
    ROTOR_BLOCKED = 24 => rotor_blocked,
    /// Homing met neither the stop nor the switch within its travel.
    HOMING_FAILED = 25 => homing_failed,
    /// A start-up step ran past its time bound, or its rotor never settled.
    LIFECYCLE_TIMEOUT = 26 => lifecycle_timeout,
    /// Power-stage temperature at `power_stage.temperature_trip_c`.
    POWER_STAGE_OVERTEMP = 27 => power_stage_overtemp,
    /// A setpoint stream stopped arriving for `stream.timeout_s`.
    STREAM_TIMEOUT = 28 => stream_timeout,
    /// The board's hardware overcurrent break is not armed: its start-up
    /// self-test found a comparator high with the bridge off (board-reported,
    /// stands until reset). The bridge never enables without it.
    NO_HARDWARE_BREAK = 29 => no_hardware_break,
    /// The option bytes let a pin select the boot mode, and on this board
    /// that pin carries a load (the ESC1's PB8/BOOT0 is the brake output):
    /// a reset could start the ROM bootloader instead of the drive
    /// (board-reported, stands until the option bytes are set and the chip
    /// reset). The bridge never enables.
    BOOT_OPTION_BYTES = 30 => boot_option_bytes,
    /// The holding brake's state feedback disagrees with what the drive
    /// commands, for longer than the brake takes to move (board-reported):
    /// a brake that will not open, or one that will not hold. Controlled
    /// stop: the bridge holds the load, since the brake may not.
    BRAKE_FEEDBACK = 31 => brake_feedback,
}

impl FaultSet {
    pub const NONE: Self = Self::empty();

    /// Faults whose reaction is a controlled stop, not switching off. The
    /// motor, its sensors and the bridge still work (with an open phase, two
    /// phases still make torque over most of a turn); only the motion is
    /// wrong. Switching off would let a vertical payload back-drive the
    /// screw (η ≈ 0.89 backwards), so the drive decelerates at
    /// `faults.stop_deceleration_m_s2` and holds. All other faults mean the
    /// drive cannot trust its measurements or its power stage: bridge off.
    pub const CONTROLLED_STOP: Self = Self::POSITION_FOLLOWING
            .union(Self::SPEED_FOLLOWING)
            .union(Self::SOFT_LIMIT)
            .union(Self::OBSERVER_OUT_OF_BOUNDS)
            .union(Self::OPEN_PHASE)
            .union(Self::HOMING_FAILED)
            .union(Self::STREAM_TIMEOUT)
            .union(Self::BRAKE_FEEDBACK);

    /// Faults a start-up step raises: the step is refused for good (until
    /// cleared), never enabled around.
    pub const LIFECYCLE: Self = Self::CALIBRATION_FAILED
            .union(Self::ENCODER_NO_SIGNAL)
            .union(Self::BRAKE_SLIP)
            .union(Self::WRONG_DIRECTION)
            .union(Self::WRONG_POLE_PAIRS)
            .union(Self::ROTOR_BLOCKED)
            .union(Self::HOMING_FAILED)
            .union(Self::LIFECYCLE_TIMEOUT);

    /// Conditions the board reports that stand until the board itself says
    /// they are gone ([`crate::Controller::report_board_condition`]): a
    /// clear does not remove them while they stand.
    pub const BOARD_CONDITIONS: Self = Self::NO_HARDWARE_BREAK.union(Self::BOOT_OPTION_BYTES).union(Self::BRAKE_FEEDBACK);

    /// The short names of the faults in this set, in bit order.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::ALL.iter().filter(move |(bit, _)| self.contains(*bit)).map(|(_, name)| *name)
    }

    /// True if every latched fault is one that calls for a controlled stop.
    pub const fn only_controlled_stop(self) -> bool {
        !self.is_empty() && self.difference(Self::CONTROLLED_STOP).is_empty()
    }
}

// `ALL` lists the faults in bit order (the logs' and reports' names by index).
const _: () = {
    let mut rest: &[(FaultSet, &str)] = &FaultSet::ALL;
    let mut bit = 1u32;
    while let [(fault, _), tail @ ..] = rest {
        assert!(fault.bits() == bit, "FaultSet::ALL must list the faults in bit order");
        bit = bit.wrapping_shl(1);
        rest = tail;
    }
};

impl core::fmt::Debug for FaultSet {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("FaultSet(")?;
        if self.is_empty() {
            f.write_str("none")?;
        }
        for (i, name) in self.names().enumerate() {
            if i > 0 {
                f.write_str("|")?;
            }
            f.write_str(name)?;
        }
        f.write_str(")")
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for FaultSet {
    fn format(&self, f: defmt::Formatter) {
        if self.is_empty() {
            defmt::write!(f, "none");
        }
        for (i, name) in self.names().enumerate() {
            if i > 0 {
                defmt::write!(f, "|");
            }
            defmt::write!(f, "{=str}", name);
        }
    }
}
