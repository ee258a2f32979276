//! Why a parameter, stream point, capture or test request was refused: one
//! code per reason on the wire, its text on the host.
//!
//! The drive sends [`Reason`] (one byte); the host tool, which links this
//! same crate, shows [`Reason::text`]. The texts are what the drive used
//! to send, word for word, so a user reads the same "what and why"; only
//! the image no longer carries them (≈ 3 KB of strings and their copying
//! into replies). `Reason::text` is never called on the board (the log
//! prints the variant's name through defmt, whose strings are not in flash).
//!
//! The reasons are the core's: parameter validation, the scope, the test
//! signals and the stream refuse with them; the protocol carries them.

use postcard_schema::Schema;
use serde::{Deserialize, Serialize};

macro_rules! reasons {
    ($($(#[$doc:meta])* $name:ident = $text:literal,)*) => {
        /// A refusal's reason (see the module documentation).
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Schema)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub enum Reason {
            $($(#[$doc])* $name,)*
        }

        impl Reason {
            /// The reason as the user reads it.
            pub const fn text(self) -> &'static str {
                match self {
                    $(Self::$name => $text,)*
                }
            }
        }
    };
}

reasons! {
    // ---- a parameter's value (`ControlParams::validate`, `ParamSet`) ----
    MustBeFinite = "must be finite",
    MustBePositive = "must be > 0",
    MustBeNonNegative = "must be >= 0",
    MustBeAtLeastOne = "must be >= 1",
    MustBeAtMostOne = "must be <= 1",
    MustBeAtMostTwo = "must be <= 2",
    BeyondHardwareRating = "beyond the drive hardware's rating (the board's current, bus voltage or overcurrent trip)",
    MustBeBelowOne = "must be < 1",
    MustBeFiniteAboveOne = "must be finite and > 1",
    MustBeOneOrMinusOne = "must be 1 or -1",
    MultipleOfSpeedDivider = "must be a multiple of speed_loop_divider",
    CountsPerRevTooHigh = "must be <= 32768",
    MustExceedStrokeMin = "must exceed stroke_min_m",
    TripBelowCurrentLimit = "must be >= limits.current_max_a, or normal operation trips",
    MustExceedBusUndervoltage = "must exceed bus_undervoltage_v",
    MarginNotBelowOvertravel = "must be below stroke_overtravel_m, or a controlled stop ends in a trip",
    StopDecelerationTooLow = "must be >= trajectory.max_acceleration_m_s2, or planned moves trip the soft limits",
    AboveObserverShiftMax = "must be <= faults.observer_shift_max_m",
    AboveCurrentLimit = "must be <= limits.current_max_a",
    AbovePeakRating = "above the motor or inverter peak rating (control.ratings)",
    AboveInverterPeakRating = "above control.ratings.inverter_peak_current_a",
    AboveBusRating = "above control.ratings.bus_max_voltage_v",
    AboveSpeedRating = "above control.ratings.speed_max_rad_s",
    BlockedRatioTooHigh = "must be below 1 - ratio_tolerance",
    AboveTrajectoryVelocity = "must be <= trajectory.max_velocity_m_s",
    MustExceedTemperatureFoldback = "must exceed temperature_foldback_c",
    MustExceedRegenStart = "must exceed regen_bus_start_v",
    RegenAboveOvervoltage = "must be <= faults.bus_overvoltage_v, or regeneration trips the drive first",
    TimeoutBelowPeriodMax = "must be >= stream.period_max_s",
    BeyondScrewSpeedRating = "above the screw's and motor's speed rating at the rod (control.ratings.speed_max_rad_s through the screw lead)",
    ProtectionTimeTooLong = "a protection's time must be <= 1 s, or it would never act",
    ProtectionLengthTooLong = "a protection's distance must be <= 50 mm, or it would never act",
    AboveNyquist = "above half the PWM rate",
    BeyondPhysicalRange = "beyond the physical range of its unit",
    GainAboveInnerBandwidth = "puts its loop's crossover above what the loop inside it carries (current: 1/8 of the PWM rate; speed: 0.3 of current and the torque filter's corner; position: the speed loop's)",
    IntegralAboveCrossover = "integral corner ki/kp above twice its loop's crossover",
    NoSuchLegSlot = "must be 0..=5 (a slot of the CAN setpoint frame)",
    NoSuchVariant = "no such variant",
    TelemetryFieldBits = "telemetry.fields: bits beyond the last TelemetryField",
    TelemetryRateTooHigh = "telemetry.rate_hz: above the position-loop rate (the record's rate)",

    // ---- test signals (`Controller::start_test`, the server's checks) ----
    FaultsLatched = "faults latched",
    NotRunning = "not running (enable first)",
    TestRunning = "a test is already running",
    MoveInProgress = "a move or stream is in progress",
    BrakeOpening = "the brake is still opening",
    DurationOutOfRange = "duration not in (0, 60] s",
    AmplitudeNotFinite = "amplitude not finite",
    CurrentStepBeyondLimit = "current step beyond limits.current_max_a",
    CurrentStepPlusHoldBeyondLimit = "current step plus hold current beyond the current limit",
    NotHomedStrokeUnknown = "not homed: the stroke is unknown",
    SpeedStepBeyondLimit = "speed step beyond limits.speed_max_rad_s",
    SpeedStepLeavesStroke = "speed step would leave the stroke",
    DistanceNotFinite = "distance not finite",
    PositionStepBeyondFollowingError = "position step not below faults.position_following_error_m",
    PositionStepBeyondStroke = "position step beyond the stroke",
    ChirpArgumentNotFinite = "chirp argument not finite",
    ChirpAmplitudeNegative = "chirp amplitude negative",
    ChirpFrequencyNotPositive = "chirp frequency not positive",
    ChirpAboveNyquist = "chirp frequency not below the loop's Nyquist",
    ChirpPlusHoldBeyondLimit = "chirp plus hold current beyond the current limit",
    ChirpBeyondSpeedLimit = "chirp beyond limits.speed_max_rad_s",
    ChirpBeyondFollowingError = "chirp not below faults.position_following_error_m",
    ChirpBeyondStroke = "chirp beyond the stroke",
    TestArguments = "amplitude not finite, or a duration or frequency not > 0",

    // ---- capture (`capture`, the server's checks, the board's link) ----
    NoCaptureStore = "no capture store attached",
    NoSignals = "no signals",
    TooManySignals = "more than 4 signals",
    DecimationZero = "decimation 0",
    TooFewSamples = "fewer than 2 samples",
    CaptureBufferTooSmall = "samples x signals beyond the 4096-value buffer",
    PreTriggerNotBelowSamples = "pre-trigger not below samples",
    FullScaleNotPositive = "a signal's full scale is not positive (ratings, stroke)",
    CaptureNotArmed = "capture not armed",
    CaptureNotDone = "capture not done",
    NoSuchSignal = "no such signal in this capture",
    StartBeyondRecord = "start beyond the record",
    DecimationMustBePositive = "decimation must be >= 1",
    SamplesMustBePositive = "samples must be >= 1",
    PreTriggerBeyondSamples = "pre_trigger beyond samples",
    CountBeyondChunk = "count beyond CAPTURE_CHUNK_MAX",
    MoreSignalsThanTheBoardRecords = "capture: more signals than the board records",
    ChunkTooLong = "capture chunk too long",
    /// The board's link: the PWM interrupt did not answer in time.
    NoAnswer = "(link: the PWM interrupt did not answer)",

    // ---- stream points (the server's checks, the controller's refusal) ----
    RefusedFaultsLatched = "refused: faults latched",
    RefusedNotRunning = "refused: drive not running",
    RefusedNotDisabled = "refused: drive not disabled",
    RefusedMoveInProgress = "refused: a move is in progress",
    RefusedNotFinite = "refused: value not finite",
    RefusedOutOfRange = "refused: value out of range",
    RefusedBusLow = "refused: bus voltage low",
    RefusedNotCalibrated = "refused: currents not calibrated",
    RefusedNotCommutated = "refused: not commutated",
    RefusedNotHomed = "refused: not homed",
    PositionNotFinite = "position_m not finite",
    VelocityNotFinite = "velocity_m_s not finite",
    ForceNotFinite = "force_n not finite",
    ForceBeyondThrust = "|force_n| above the motor's peak thrust (control.ratings.motor_peak_current_a through the screw)",
    BelowStrokeMin = "position_m below control.limits.stroke_min_m",
    BeyondStrokeMax = "position_m beyond control.limits.stroke_max_m",
    BeyondMaxVelocity = "velocity_m_s beyond control.trajectory.max_velocity_m_s",
    StreamGap = "gap beyond control.stream.timeout_s: the stream has ended",
    StreamJump = "jump beyond control.trajectory.max_velocity_m_s since the last point",

    // ---- an observer weight block (`observer::block`) ----
    ObserverInputCount = "input count is not this firmware's network's",
    ObserverHiddenCount = "hidden unit count is not this firmware's network's",
    ObserverWordCount = "word count or word range is not this firmware's block's",
    ObserverStructureHash = "structure hash is not this firmware's network's (other inputs, order, kind or size)",
    ObserverRangeEmpty = "input_max must be above input_min",
    ObserverScaleMismatch = "input_scale is not 2 / (input_max - input_min): normalisation does not match the range",
    ObserverDecayMismatch = "log2_decay is not log2(e) / (2 width^2)",
    ObserverShiftBeyondBound = "prediction beyond control.faults.observer_shift_max_m in the trained range",
    ObserverNoUpload = "no upload begun (send Begin first)",
    ObserverWordMissing = "words missing: a chunk was not received",

    // ---- a stream's agreement with itself (`protocol::server`) ----
    VelocityDisagreesWithSteps = "velocity_m_s disagrees with the position steps over the drive's clock (averaged over control.stream.timeout_s) by more than control.stream.velocity_mismatch_max_m_s: a velocity column in other units, or points recorded at another rate than they arrive",
    MismatchAboveHalfVelocity = "must be <= half of trajectory.max_velocity_m_s, or a stream whose velocity says rest while it moves at full speed passes",

    // ---- a protection's bound that would check nothing ----
    EncoderBoundNotBelowHalfTurn = "must be below half of encoder.counts_per_rev: a jump of half a turn cannot be told from one the other way",
    EmfMismatchAboveQuarterRating = "must be <= a quarter of control.ratings.speed_max_rad_s, or a frozen encoder under a load that slips the rotor goes unseen",

    // ---- observer weights and the force input they were trained on ----
    ObserverTrainedOnLoadCell = "weights trained on the load cell, but control.compensation.force_from_estimate = true feeds the observer the drive's force estimate: upload weights trained on the estimate, or set force_from_estimate false",
    ObserverTrainedOnEstimate = "weights trained on the drive's force estimate, but control.compensation.force_from_estimate = false feeds the observer the load cell: set force_from_estimate true first, or upload weights trained on the load cell",
    ObserverWeightsForOtherForce = "uploaded observer weights run, trained for the present force input: switch back to the compiled weights (observer compiled) or upload weights for the new force input first",

    // ---- a test asked before the axis has held still since `Enable` ----
    AxisNotYetSettled = "the axis has not yet held still since Enable (the start-up torque watch still runs): a test from here would carry the load's hand-over from the brake",
}

impl core::fmt::Display for Reason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.text())
    }
}
