//! The cases: random successful power-ups and one of each failure.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use servo_core::FaultSet;
use std::f64::consts::TAU;

/// What is wrong with the rig in a failure case.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Failure {
    None,
    /// The brake never lets go (seized): the rotor cannot turn.
    BlockedRotor,
    /// Motor phases b and c swapped at the terminals.
    SwappedPhases,
    /// The drive believes 5 pole pairs; the motor has 4.
    WrongPolePairs,
    /// The encoder cable is off: the counter never moves.
    EncoderUnplugged,
    /// The bus sags by 5 V while the current offsets are averaged.
    SupplySagDuringCalibration,
    /// The brake disc is worn: the load's back-drive torque plus half the
    /// commutation's test torque (1.4 N·m on the shipped rig), enough for
    /// the load alone, not for the load and the test.
    BrakeSlips,
    /// Homing by switch, but the switch is never reached.
    HomeSwitchNeverTriggers,
    /// Homing to the hard stop, but the stop is beyond the travel bound.
    HardStopNeverMet,
    /// A commutation error no check sees: the offset is stored as known
    /// (`startup.commutation_known`, e.g. kept from before the encoder was
    /// remounted) and is a quarter electrical turn off, so the motor makes
    /// no torque. The torque watch must close the brake.
    OffsetQuarterTurnOff,
    /// As above, a quarter turn off the other way: the torque is as missing,
    /// and a correction tried forwards reverses it.
    OffsetQuarterTurnBack,
    /// As above, half a turn off: the torque is reversed, and the loops'
    /// correction drives the rod away.
    OffsetHalfTurnOff,
}

impl Failure {
    /// The fault the drive must name.
    pub fn expected_fault(self) -> Option<FaultSet> {
        match self {
            Self::None => None,
            Self::BlockedRotor => Some(FaultSet::ROTOR_BLOCKED),
            Self::SwappedPhases => Some(FaultSet::WRONG_DIRECTION),
            Self::WrongPolePairs => Some(FaultSet::WRONG_POLE_PAIRS),
            Self::EncoderUnplugged => Some(FaultSet::ENCODER_NO_SIGNAL),
            Self::SupplySagDuringCalibration => Some(FaultSet::CALIBRATION_FAILED),
            Self::BrakeSlips => Some(FaultSet::BRAKE_SLIP),
            Self::HomeSwitchNeverTriggers | Self::HardStopNeverMet => Some(FaultSet::HOMING_FAILED),
            Self::OffsetQuarterTurnOff | Self::OffsetQuarterTurnBack | Self::OffsetHalfTurnOff => Some(FaultSet::WRONG_DIRECTION),
        }
    }

    /// The stored commutation offset's error, electrical radians.
    pub fn offset_error_rad(self) -> Option<f64> {
        match self {
            Self::OffsetQuarterTurnOff => Some(0.5 * std::f64::consts::PI),
            Self::OffsetQuarterTurnBack => Some(-0.5 * std::f64::consts::PI),
            Self::OffsetHalfTurnOff => Some(std::f64::consts::PI),
            _ => None,
        }
    }

    pub const ALL: [Self; 11] = [
        Self::BlockedRotor,
        Self::SwappedPhases,
        Self::WrongPolePairs,
        Self::EncoderUnplugged,
        Self::SupplySagDuringCalibration,
        Self::BrakeSlips,
        Self::HomeSwitchNeverTriggers,
        Self::HardStopNeverMet,
        Self::OffsetQuarterTurnOff,
        Self::OffsetQuarterTurnBack,
        Self::OffsetHalfTurnOff,
    ];
}

/// One power-up: where the rotor and the rod are, how the encoder and the
/// amplifiers sit, and what (if anything) is wrong.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PowerUpCase {
    pub name: String,
    pub seed: u64,
    /// Rotor angle, radians: sets the rod position (`x0 + L θ/2π`).
    pub rotor_angle_rad: f64,
    pub rod_position_m: f64,
    /// Mechanical angle of the encoder's count zero.
    pub encoder_zero_rad: f64,
    pub current_offset_a: [f64; 3],
    pub failure: Failure,
}

/// `successes` random power-ups with rods in `[rod_min_m, rod_max_m]`, then
/// one of each failure at a random rotor angle near the bottom of the stroke.
pub fn suite(successes: usize, rod_min_m: f64, rod_max_m: f64, lead_m: f64, seed: u64) -> Vec<PowerUpCase> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let draw = |name: String, failure: Failure, lo: f64, hi: f64, rng: &mut ChaCha8Rng| {
        let rod = rng.random_range(lo..hi);
        PowerUpCase {
            name,
            seed: rng.random(),
            rotor_angle_rad: rod / lead_m * TAU,
            rod_position_m: rod,
            encoder_zero_rad: rng.random_range(0.0..TAU),
            current_offset_a: std::array::from_fn(|_| rng.random_range(-0.5..0.5)),
            failure,
        }
    };
    let mut cases: Vec<_> = (0..successes).map(|k| draw(format!("power-up {:02}", k + 1), Failure::None, rod_min_m, rod_max_m, &mut rng)).collect();
    for f in Failure::ALL {
        cases.push(draw(format!("{f:?}"), f, rod_min_m, (rod_min_m + 0.02).min(rod_max_m), &mut rng));
    }
    cases
}
