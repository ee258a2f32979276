//! Board calibration: every constant that turns a raw code into SI units,
//! in one place. Sources: UM2516 schematic and ST MCSDK's B-G431B-ESC1 power
//! board description.

/// ADC reference (VDDA = VREF+ = 3.3 V on this board) and full scale.
pub const ADC_VREF_V: f32 = 3.3;
pub const ADC_FULL_SCALE: f32 = 4095.0;
pub const VOLTS_PER_CODE: f32 = ADC_VREF_V / ADC_FULL_SCALE;

/// Low-side shunt resistance (R003).
pub const SHUNT_OHM: f32 = 0.003;
/// Internal PGA gain of OPAMP1/2/3 (PGA 16, gain network grounded on VINM0).
pub const PGA_GAIN: f32 = 16.0;
/// Resistor network between shunt and OPAMP input (MCSDK "GON" 0.571, 4/7).
pub const SHUNT_NETWORK_GAIN: f32 = 4.0 / 7.0;
/// Shunt voltage to ADC input: 16 × 4/7 = 9.14 (MCSDK AMPLIFICATION_GAIN).
pub const CURRENT_AMP_GAIN: f32 = PGA_GAIN * SHUNT_NETWORK_GAIN;
/// A current *into* the motor flows up through the low-side shunt, so the
/// amplifier output falls: phase current = −(code − offset) × scale.
/// (SimpleFOC's ESC1 configuration uses the same sign: gain −64/7.)
pub const CURRENT_SENSE_SIGN: f32 = -1.0;
/// Phase current per ADC code (≈ 29.4 mA; ±1.65 V swing ≈ ±60 A).
pub const AMPS_PER_CODE: f32 = CURRENT_SENSE_SIGN * VOLTS_PER_CODE / (SHUNT_OHM * CURRENT_AMP_GAIN);
/// Bias on the OPAMP non-inverting input at zero current (MCSDK
/// "VPOL/16" = 0.1286 V), hence the output offset 16 × 0.1286 = 2.057 V.
pub const SHUNT_BIAS_V: f32 = 0.128_562_5;
/// Expected zero-current code; the start-up calibration measures the real one.
pub const CURRENT_OFFSET_NOMINAL_CODE: f32 = PGA_GAIN * SHUNT_BIAS_V / VOLTS_PER_CODE;
/// A measured offset further than this from nominal means the front end
/// is not configured as assumed (or the board is not an ESC1): refuse.
pub const CURRENT_OFFSET_TOLERANCE_CODE: f32 = 300.0;

/// VBUS divider 18 kΩ / (169 kΩ + 18 kΩ) (MCSDK VBUS_PARTITIONING_FACTOR).
pub const VBUS_DIVIDER: f32 = 18.0 / (169.0 + 18.0);
pub const VBUS_VOLTS_PER_CODE: f32 = VOLTS_PER_CODE / VBUS_DIVIDER;

/// NTC network, linearised by ST: V = 1.4 V + 19 mV/°C × (T − 25 °C).
pub const NTC_V_AT_T0: f32 = 1.4;
pub const NTC_T0_C: f32 = 25.0;
pub const NTC_V_PER_C: f32 = 0.019;

/// Hardware overcurrent trip (MCSDK OCP threshold for this board).
pub const HW_OCP_TRIP_A: f32 = 45.0;
/// Comparator threshold: the OPAMP input node, bias + 4/7 × shunt voltage,
/// rises with current *out of* the motor phase; DAC3 12-bit code 255
/// (MCSDK writes the same 0.2057 V as 4083 in 16-bit left alignment).
pub const HW_OCP_DAC_CODE: u16 =
    ((SHUNT_BIAS_V + SHUNT_NETWORK_GAIN * SHUNT_OHM * HW_OCP_TRIP_A) / VOLTS_PER_CODE + 0.5) as u16;

/// Power stage ratings: 6S LiPo (MCSDK board max 28 V), 40 A peak.
pub const BOARD_MAX_BUS_V: f32 = 28.0;
pub const BOARD_MAX_CURRENT_A: f32 = 40.0;
