//! The parameters as a table of leaves: leaf `i` of `ControlParams` (the
//! order of the `miniconf::Tree` paths, depth-first in declaration order)
//! is at byte `offset` of the struct and has type `kind`.
//!
//! Why a table next to the `miniconf` tree: the tree's typed lookup
//! (`TreeAny`) is ≈ 5 KB of derived code per use in the image, and the
//! record's postcard codec another ≈ 7 KB; the drive gets, sets and
//! stores leaves through this table instead (≈ 350 bytes of data). The
//! paths stay the tree's (`protocol::params` resolves a path to its index
//! through the tree's static schema). A test sets every leaf through one
//! and reads it through the other, so the two cannot drift apart unseen.

use core::mem::offset_of;

use super::{ControlParams, HomingMethod};
use super::value::{Value, ValueKind};

/// One parameter: where it is in `ControlParams` and its type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Leaf {
    pub offset: u16,
    pub kind: ValueKind,
}

/// The type of a leaf, from its Rust type (so the table cannot mistype one).
pub trait LeafType {
    const KIND: ValueKind;
}
impl LeafType for f32 {
    const KIND: ValueKind = ValueKind::F32;
}
impl LeafType for u32 {
    const KIND: ValueKind = ValueKind::U32;
}
impl LeafType for i32 {
    const KIND: ValueKind = ValueKind::I32;
}
impl LeafType for bool {
    const KIND: ValueKind = ValueKind::Bool;
}
impl LeafType for HomingMethod {
    const KIND: ValueKind = ValueKind::Variant;
}

const fn kind_of<T: LeafType>(_: &T) -> ValueKind {
    T::KIND
}

macro_rules! leaves {
    ($($($f:ident).+,)*) => {
        /// Every leaf, in path order.
        pub const LEAVES: [Leaf; LEAF_COUNT] = [$(Leaf {
            offset: offset_of!(ControlParams, $($f).+) as u16,
            kind: kind_of(&ControlParams::DEFAULT.$($f).+),
        },)*];
        /// [`LEAVES`] as the image holds it, offsets and kinds apart: three
        /// bytes a leaf instead of four (`Leaf` pads its `u16` and one-byte
        /// kind).
        static OFFSETS: [u16; LEAF_COUNT] = [$(offset_of!(ControlParams, $($f).+) as u16,)*];
        static KINDS: [ValueKind; LEAF_COUNT] = [$(kind_of(&ControlParams::DEFAULT.$($f).+),)*];
        /// Number of parameters.
        pub const LEAF_COUNT: usize = PATHS.len();
        /// The leaves' paths, for the host and compile-time messages.
        const PATHS: &[&str] = &[$(concat!("control.", stringify!($($f).+)),)*];
    };
}

leaves! {
    motor.pole_pairs,
    motor.phase_resistance_ohm,
    motor.inductance_d_h,
    motor.inductance_q_h,
    motor.flux_linkage_wb,
    drive_train.screw_lead_m,
    drive_train.screw_efficiency,
    drive_train.rotating_inertia_kg_m2,
    drive_train.moving_mass_kg,
    drive_train.viscous_friction_n_m_s_rad,
    drive_train.coulomb_friction_n_m,
    drive_train.friction_feedforward_speed_rad_s,
    drive_train.friction_feedforward_gain,
    rates.pwm_frequency_hz,
    rates.speed_loop_divider,
    rates.position_loop_divider,
    current_pi.kp,
    current_pi.ki,
    speed_pi.kp,
    speed_pi.ki,
    speed_setpoint_weight,
    torque_filter_hz,
    position_kp_per_s,
    encoder.counts_per_rev,
    encoder.direction,
    encoder.electrical_offset_rad,
    encoder.pll_kp_per_s,
    encoder.pll_ki_per_s2,
    trajectory.max_velocity_m_s,
    trajectory.max_acceleration_m_s2,
    trajectory.max_jerk_m_s3,
    limits.current_max_a,
    limits.copper_power_max_w,
    limits.speed_max_rad_s,
    limits.stroke_min_m,
    limits.stroke_max_m,
    limits.max_modulation,
    faults.overcurrent_trip_a,
    faults.bus_overvoltage_v,
    faults.bus_undervoltage_v,
    faults.encoder_max_step_counts,
    faults.encoder_max_innovation_counts,
    faults.position_following_error_m,
    faults.stroke_overtravel_m,
    faults.speed_following_error_rad_s,
    faults.speed_following_time_s,
    faults.encoder_lost_speed_rad_s,
    faults.encoder_lost_time_s,
    faults.stroke_soft_margin_m,
    faults.stop_deceleration_m_s2,
    faults.observer_shift_max_m,
    faults.current_sum_max_a,
    faults.current_sum_periods,
    faults.stop_following_error_m,
    faults.open_phase_window_s,
    faults.open_phase_current_a,
    faults.open_phase_ratio,
    load_estimate.filter_hz,
    startup.commutation_known,
    startup.homed,
    startup.expected_load_force_n,
    startup.run_at_power_up,
    calibration.duration_s,
    calibration.offset_max_a,
    calibration.noise_max_a,
    calibration.bus_ripple_max_v,
    commutation.test_current_a,
    commutation.ramp_s,
    commutation.sweep_s,
    commutation.settle_s,
    commutation.settle_speed_rad_s,
    commutation.settle_timeout_s,
    commutation.min_amplitude_counts,
    commutation.max_twist_rad,
    commutation.hold_current_d_a,
    commutation.check_angle_rad,
    commutation.check_time_s,
    commutation.ratio_tolerance,
    commutation.blocked_ratio,
    commutation.timeout_s,
    homing.method,
    homing.direction,
    homing.speed_m_s,
    homing.current_max_a,
    homing.contact_following_m,
    homing.contact_speed_rad_s,
    homing.contact_time_s,
    homing.home_position_m,
    homing.backoff_m,
    homing.travel_max_m,
    homing.jog_speed_max_m_s,
    power_stage.temperature_foldback_c,
    power_stage.temperature_trip_c,
    power_stage.regen_bus_start_v,
    power_stage.regen_bus_max_v,
    power_stage.regen_power_max_w,
    power_stage.emf_speed_mismatch_rad_s,
    power_stage.emf_mismatch_time_s,
    stream.period_max_s,
    stream.timeout_s,
    stream.leg_index,
    stream.can_termination,
    stream.velocity_mismatch_max_m_s,
    thermal.continuous_current_a,
    thermal.time_constant_s,
    thermal.foldback_start,
    thermal.trip_level,
    ratings.motor_peak_current_a,
    ratings.inverter_peak_current_a,
    ratings.bus_max_voltage_v,
    ratings.speed_max_rad_s,
    compensation.enabled_at_start,
    compensation.shift_max_m,
    compensation.shift_rate_max_m_s,
    compensation.force_from_estimate,
    brake.fitted,
    brake.release_time_s,
    brake.engage_time_s,
    brake.holding_torque_n_m,
    brake.preload_time_s,
    brake.torque_watch_travel_m,
    brake.handover_slip_m,
}

// Offsets fit the table's u16 and every leaf is 4 bytes or less (the
// record's slot).
const _: () = assert!(core::mem::size_of::<ControlParams>() <= u16::MAX as usize);

/// The index of the leaf at byte `offset` of `ControlParams` (for
/// `validate`, at compile time: `leaf!(speed_pi.kp)`); `u16::MAX` if none.
pub const fn index_at(offset: usize) -> u16 {
    let mut rest: &[Leaf] = &LEAVES;
    let mut i: u16 = 0;
    while let [first, tail @ ..] = rest {
        if first.offset as usize == offset {
            return i;
        }
        rest = tail;
        i = i.wrapping_add(1);
    }
    u16::MAX
}

/// The leaf index of a field path of `ControlParams`, as a constant.
#[macro_export]
#[doc(hidden)]
macro_rules! leaf {
    ($($f:ident).+) => {{
        const I: u16 = $crate::params::leaves::index_at(core::mem::offset_of!($crate::params::ControlParams, $($f).+));
        const _: () = assert!(I != u16::MAX, "not a leaf");
        I
    }};
}

/// The path of leaf `index` (`""` if there is none). For the host and for
/// compile-time messages: the drive names leaves through the tree
/// (`protocol::params::name`), so this table stays out of the image.
pub const fn path(index: usize) -> &'static str {
    let mut rest: &[&str] = PATHS;
    let mut i = 0;
    while let [first, tail @ ..] = rest {
        if i == index {
            return first;
        }
        rest = tail;
        i = i.wrapping_add(1);
    }
    ""
}

/// Why a leaf could not be written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafError {
    /// No leaf with this index.
    Unknown,
    /// The leaf has this type, not the value's.
    WrongType(ValueKind),
    /// An enum parameter has no variant with this index.
    NoSuchVariant,
}

/// Enum parameters by variant index (`homing.method`: 0 hard stop, 1 switch).
const fn homing_method_index(m: HomingMethod) -> u8 {
    match m {
        HomingMethod::HardStop => 0,
        HomingMethod::Switch => 1,
    }
}

const fn homing_method(index: u8) -> Option<HomingMethod> {
    match index {
        0 => Some(HomingMethod::HardStop),
        1 => Some(HomingMethod::Switch),
        _ => None,
    }
}

/// Leaf `index`, if there is one.
pub fn leaf(index: usize) -> Option<Leaf> {
    Some(Leaf { offset: *OFFSETS.get(index)?, kind: *KINDS.get(index)? })
}

/// Whether leaf `index` holds the same value in `a` and `b` (as `get`'s
/// values compare: floats by value), read in place: no `Value` built, for
/// the PWM interrupt's parameter apply. An unknown index counts as same.
#[inline(always)]
pub fn same(a: &ControlParams, b: &ControlParams, index: usize) -> bool {
    let Some(l) = leaf(index) else { return true };
    let pa = (a as *const ControlParams).cast::<u8>().wrapping_add(usize::from(l.offset));
    let pb = (b as *const ControlParams).cast::<u8>().wrapping_add(usize::from(l.offset));
    // SAFETY: as in `get`: both point to an initialised, aligned value of
    // the leaf's own type inside `*a` and `*b`.
    unsafe {
        match l.kind {
            ValueKind::F32 => *pa.cast::<f32>() == *pb.cast::<f32>(),
            ValueKind::U32 | ValueKind::I32 => *pa.cast::<u32>() == *pb.cast::<u32>(),
            ValueKind::Bool => *pa.cast::<bool>() == *pb.cast::<bool>(),
            ValueKind::Variant => *pa.cast::<HomingMethod>() == *pb.cast::<HomingMethod>(),
        }
    }
}

/// The value of leaf `index` of `p`.
pub fn get(p: &ControlParams, index: usize) -> Option<Value> {
    let l = leaf(index)?;
    let at = (p as *const ControlParams).cast::<u8>().wrapping_add(usize::from(l.offset));
    // SAFETY: `LEAVES` holds the offset of a field of `ControlParams`
    // (`offset_of!`) and that field's type (`LeafType`, from the field
    // itself), so `at` points to an initialised, aligned value of the
    // type read here, inside `*p`.
    Some(unsafe {
        match l.kind {
            ValueKind::F32 => Value::F32(*at.cast::<f32>()),
            ValueKind::U32 => Value::U32(*at.cast::<u32>()),
            ValueKind::I32 => Value::I32(*at.cast::<i32>()),
            ValueKind::Bool => Value::Bool(*at.cast::<bool>()),
            ValueKind::Variant => Value::Variant(homing_method_index(*at.cast::<HomingMethod>())),
        }
    })
}

/// Writes `value` to leaf `index` of `p` (no validation: that is the
/// caller's, on the whole set). Nothing changes on an error.
pub fn set(p: &mut ControlParams, index: usize, value: Value) -> Result<(), LeafError> {
    let l = leaf(index).ok_or(LeafError::Unknown)?;
    let at = (p as *mut ControlParams).cast::<u8>().wrapping_add(usize::from(l.offset));
    // SAFETY: as in `get`; each arm writes a value of the leaf's own type
    // (the kind matched), a valid one (`homing_method` only yields variants).
    unsafe {
        match (l.kind, value) {
            (ValueKind::F32, Value::F32(v)) => *at.cast::<f32>() = v,
            (ValueKind::U32, Value::U32(v)) => *at.cast::<u32>() = v,
            (ValueKind::I32, Value::I32(v)) => *at.cast::<i32>() = v,
            (ValueKind::Bool, Value::Bool(v)) => *at.cast::<bool>() = v,
            (ValueKind::Variant, Value::Variant(i)) => {
                *at.cast::<HomingMethod>() = homing_method(i).ok_or(LeafError::NoSuchVariant)?;
            }
            (kind, _) => return Err(LeafError::WrongType(kind)),
        }
    }
    Ok(())
}

/// Leaf `index` of `p` as the record stores it: 4 bytes, little-endian
/// (`f32` bits, integers, `bool` 0/1, a variant's index).
pub fn to_word(p: &ControlParams, index: usize) -> Option<u32> {
    Some(match get(p, index)? {
        Value::F32(v) => v.to_bits(),
        Value::U32(v) => v,
        Value::I32(v) => v as u32,
        Value::Bool(v) => u32::from(v),
        Value::Variant(i) => u32::from(i),
    })
}

/// Writes a record's word to leaf `index` of `p`; refused (nothing
/// written) when it is not a value of the leaf's type (a `bool` other
/// than 0/1, a variant that does not exist).
pub fn from_word(p: &mut ControlParams, index: usize, word: u32) -> Result<(), LeafError> {
    let l = leaf(index).ok_or(LeafError::Unknown)?;
    let value = match l.kind {
        ValueKind::F32 => Value::F32(f32::from_bits(word)),
        ValueKind::U32 => Value::U32(word),
        ValueKind::I32 => Value::I32(word as i32),
        ValueKind::Bool => Value::Bool(match word {
            0 => false,
            1 => true,
            _ => return Err(LeafError::WrongType(l.kind)),
        }),
        ValueKind::Variant => Value::Variant(u8::try_from(word).map_err(|_| LeafError::NoSuchVariant)?),
    };
    set(p, index, value)
}
