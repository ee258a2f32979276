//! Latched faults. A fault switches the bridge off at once and stays set until
//! an explicit clear command finds its cause gone (ODrive/MCSDK habit: the
//! operator acknowledges, the drive never re-arms by itself).

/// A set of fault bits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[derive(serde::Serialize, serde::Deserialize, postcard_schema::Schema)]
#[serde(transparent)]
pub struct FaultSet(pub u32);

impl FaultSet {
    pub const NONE: Self = Self(0);
    /// Instantaneous |i_phase| above `faults.overcurrent_trip_a`.
    pub const OVERCURRENT: Self = Self(1 << 0);
    pub const BUS_OVERVOLTAGE: Self = Self(1 << 1);
    /// Only while the bridge is enabled: a board powered from USB with the
    /// bus off must still be configurable.
    pub const BUS_UNDERVOLTAGE: Self = Self(1 << 2);
    /// The encoder moved further in one period than the motor can.
    pub const ENCODER_JUMP: Self = Self(1 << 3);
    /// |position command − motor-side position| above the threshold.
    pub const POSITION_FOLLOWING: Self = Self(1 << 4);
    /// Motor-side position beyond the stroke plus the allowed overtravel.
    pub const STROKE_OVERTRAVEL: Self = Self(1 << 5);
    /// NaN or infinity in a sensor sample.
    pub const NON_FINITE_INPUT: Self = Self(1 << 6);
    /// The parameter set failed validation; the bridge never enables.
    pub const INVALID_PARAMS: Self = Self(1 << 7);
    /// A new sample arrived before the previous step finished (board-reported).
    pub const ISR_OVERRUN: Self = Self(1 << 8);
    /// The I²t winding model passed its trip level.
    pub const MOTOR_OVERTEMP: Self = Self(1 << 9);
    /// |ω_ref − ω| stayed above the threshold.
    pub const SPEED_FOLLOWING: Self = Self(1 << 10);
    /// No encoder count while commanded to turn: lost signal or stalled rotor.
    pub const ENCODER_LOST: Self = Self(1 << 11);
    /// The motor would not stop inside the stroke (soft limit).
    pub const SOFT_LIMIT: Self = Self(1 << 12);
    /// The error observer's shift was non-finite or beyond its bound.
    pub const OBSERVER_OUT_OF_BOUNDS: Self = Self(1 << 13);
    /// The last reset came from the independent watchdog (board-reported).
    pub const WATCHDOG_RESET: Self = Self(1 << 14);
    /// The three phase currents do not sum to zero: a stuck, offset or
    /// open-circuit current sensor (a star-connected motor has no path for a
    /// common-mode current).
    pub const CURRENT_SENSOR: Self = Self(1 << 15);
    /// One phase carries no current while the reference needs it there: a
    /// broken motor lead or a dead inverter leg. The phase currents still
    /// sum to zero (the other two carry ±the same), so `CURRENT_SENSOR`
    /// cannot see it.
    pub const OPEN_PHASE: Self = Self(1 << 16);
    /// The board's comparator break switched the outputs off in hardware
    /// (board-reported): the core must not carry on as if it were driving.
    pub const BRIDGE_BREAK: Self = Self(1 << 17);
    /// A controlled stop could not hold the motion: the rod left the stop's
    /// path by more than `faults.stop_following_error_m` while the motor's
    /// present current limit gives less torque than the brake holds.
    /// Escalates to the bridge off with the holding brake engaged.
    pub const STOP_FAILED: Self = Self(1 << 18);
    /// Current-offset calibration: an offset or the noise beyond its bound,
    /// or the bus moved during the average (a sagging supply).
    pub const CALIBRATION_FAILED: Self = Self(1 << 19);
    /// Commutation: the brake-held rotor showed no twist under the test
    /// torque (encoder unplugged, or no signal).
    pub const ENCODER_NO_SIGNAL: Self = Self(1 << 20);
    /// The brake let the shaft turn further than its disc can twist: it
    /// slipped under the commutation test torque or the load alone.
    pub const BRAKE_SLIP: Self = Self(1 << 21);
    /// The check rotation went the other way: encoder direction or phase
    /// order reversed.
    pub const WRONG_DIRECTION: Self = Self(1 << 22);
    /// The check rotation's size disagrees with `motor.pole_pairs`.
    pub const WRONG_POLE_PAIRS: Self = Self(1 << 23);
    /// The rotor did not follow the check rotation: blocked.
    pub const ROTOR_BLOCKED: Self = Self(1 << 24);
    /// Homing met neither the stop nor the switch within its travel.
    pub const HOMING_FAILED: Self = Self(1 << 25);
    /// A start-up step ran past its time bound, or its rotor never settled.
    pub const LIFECYCLE_TIMEOUT: Self = Self(1 << 26);
    /// Power-stage temperature at `power_stage.temperature_trip_c`.
    pub const POWER_STAGE_OVERTEMP: Self = Self(1 << 27);
    /// A setpoint stream stopped arriving for `stream.timeout_s`.
    pub const STREAM_TIMEOUT: Self = Self(1 << 28);

    /// Faults whose reaction is a controlled stop, not switching off. The
    /// motor, its sensors and the bridge still work (with an open phase, two
    /// phases still make torque over most of a turn); only the motion is
    /// wrong. Switching off would let a vertical payload back-drive the
    /// screw (η ≈ 0.89 backwards), so the drive decelerates at
    /// `faults.stop_deceleration_m_s2` and holds. All other faults mean the
    /// drive cannot trust its measurements or its power stage: bridge off.
    pub const CONTROLLED_STOP: Self = Self(
        Self::POSITION_FOLLOWING.0
            | Self::SPEED_FOLLOWING.0
            | Self::SOFT_LIMIT.0
            | Self::OBSERVER_OUT_OF_BOUNDS.0
            | Self::OPEN_PHASE.0
            | Self::HOMING_FAILED.0
            | Self::STREAM_TIMEOUT.0,
    );

    /// Faults a start-up step raises: the step is refused for good (until
    /// cleared), never enabled around.
    pub const LIFECYCLE: Self = Self(
        Self::CALIBRATION_FAILED.0
            | Self::ENCODER_NO_SIGNAL.0
            | Self::BRAKE_SLIP.0
            | Self::WRONG_DIRECTION.0
            | Self::WRONG_POLE_PAIRS.0
            | Self::ROTOR_BLOCKED.0
            | Self::HOMING_FAILED.0
            | Self::LIFECYCLE_TIMEOUT.0,
    );

    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }

    pub fn insert(&mut self, other: Self) {
        self.0 |= other.0;
    }

    pub const fn union(self, other: Self) -> Self {
        Self(self.0 | other.0)
    }

    pub const fn bits(self) -> u32 {
        self.0
    }

    pub const fn intersects(self, other: Self) -> bool {
        self.0 & other.0 != 0
    }

    pub const fn intersection(self, other: Self) -> Self {
        Self(self.0 & other.0)
    }

    pub const fn difference(self, other: Self) -> Self {
        Self(self.0 & !other.0)
    }

    /// The short names of the faults in this set, in bit order.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::ALL.iter().filter(move |(bit, _)| self.contains(*bit)).map(|(_, name)| *name)
    }

    /// True if every latched fault is one that calls for a controlled stop.
    pub const fn only_controlled_stop(self) -> bool {
        !self.is_empty() && self.difference(Self::CONTROLLED_STOP).is_empty()
    }
}

/// One list gives both [`FaultSet::ALL`] (names as strings, for the host's
/// reports) and, with the `defmt` feature, `FaultName`: the same names as a
/// C-like enum, in the same (bit) order. defmt interns an enum's variant
/// names in its `.defmt` section, which is not flashed, and sends only the
/// index; the strings of `ALL` would take ≈ 650 bytes of flash (text and
/// pointer table) in the firmware image.
macro_rules! fault_names {
    ($($bit:ident => $name:ident,)*) => {
        impl FaultSet {
            /// Every fault, with a short name for logs and reports.
            pub const ALL: [(Self, &'static str); 29] = [$((Self::$bit, stringify!($name)),)*];
        }

        /// Only its defmt format string is used (see [`FaultIndex`]).
        #[cfg(feature = "defmt")]
        #[allow(non_camel_case_types, dead_code)]
        #[derive(Clone, Copy, defmt::Format)]
        enum FaultName {
            $($name,)*
        }
    };
}

fault_names! {
    OVERCURRENT => overcurrent,
    BUS_OVERVOLTAGE => bus_overvoltage,
    BUS_UNDERVOLTAGE => bus_undervoltage,
    ENCODER_JUMP => encoder_jump,
    POSITION_FOLLOWING => position_following,
    STROKE_OVERTRAVEL => stroke_overtravel,
    NON_FINITE_INPUT => non_finite_input,
    INVALID_PARAMS => invalid_params,
    ISR_OVERRUN => isr_overrun,
    MOTOR_OVERTEMP => motor_overtemp,
    SPEED_FOLLOWING => speed_following,
    ENCODER_LOST => encoder_lost,
    SOFT_LIMIT => soft_limit,
    OBSERVER_OUT_OF_BOUNDS => observer_out_of_bounds,
    WATCHDOG_RESET => watchdog_reset,
    CURRENT_SENSOR => current_sensor,
    OPEN_PHASE => open_phase,
    BRIDGE_BREAK => bridge_break,
    STOP_FAILED => stop_failed,
    CALIBRATION_FAILED => calibration_failed,
    ENCODER_NO_SIGNAL => encoder_no_signal,
    BRAKE_SLIP => brake_slip,
    WRONG_DIRECTION => wrong_direction,
    WRONG_POLE_PAIRS => wrong_pole_pairs,
    ROTOR_BLOCKED => rotor_blocked,
    HOMING_FAILED => homing_failed,
    LIFECYCLE_TIMEOUT => lifecycle_timeout,
    POWER_STAGE_OVERTEMP => power_stage_overtemp,
    STREAM_TIMEOUT => stream_timeout,
}

// `ALL` (and so `FaultName`, whose variant i names bit i) is in bit order.
const _: () = {
    let mut rest: &[(FaultSet, &str)] = &FaultSet::ALL;
    let mut bit = 1u32;
    while let [(fault, _), tail @ ..] = rest {
        assert!(fault.0 == bit, "FaultSet::ALL must list the faults in bit order");
        bit = bit.wrapping_shl(1);
        rest = tail;
    }
};

#[cfg(feature = "defmt")]
impl defmt::Format for FaultSet {
    fn format(&self, f: defmt::Formatter) {
        if self.is_empty() {
            defmt::write!(f, "none");
            return;
        }
        let mut first = true;
        let mut bit = 1u32;
        for index in 0..FaultSet::ALL.len() as u8 {
            if self.0 & bit != 0 {
                if !first {
                    defmt::write!(f, "|");
                }
                first = false;
                defmt::write!(f, "{}", FaultIndex(index));
            }
            bit = bit.wrapping_shl(1);
        }
    }
}

/// Bit `i` of a [`FaultSet`], logged as `FaultName`'s variant `i` (the
/// same bytes as the derive writes for that variant, without the derive's
/// table of pointers to one constant per variant).
#[cfg(feature = "defmt")]
struct FaultIndex(u8);

#[cfg(feature = "defmt")]
impl defmt::Format for FaultIndex {
    /// The log macros take the two methods below; a direct caller of
    /// `format` gets the bit's index (never a panic in the core).
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "fault bit {=u8}", self.0)
    }

    fn _format_tag() -> defmt::Str {
        <FaultName as defmt::Format>::_format_tag()
    }

    fn _format_data(&self) {
        defmt::export::u8(&self.0);
    }
}
