//! What crosses the boundary between the control core and its host (the
//! STM32 ISR or the simulator): one sensor sample in, one PWM command out.

/// Everything the drive measures at one PWM centre, already in SI units.
///
/// The board converts raw ADC codes and timer counts; the core never sees
/// hardware scaling, so the simulator can feed it the same struct.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorSample {
    /// Phase currents a, b, c in amperes (positive into the motor).
    pub phase_current_a: [f32; 3],
    /// Raw quadrature counter value. It wraps at 2^16 like the STM32 timer;
    /// the core unwraps it, so any 16-bit counter start value works.
    pub encoder_count: u16,
    /// DC-link voltage in volts.
    pub bus_voltage_v: f32,
    /// Piston-rod (terminal) position from a linear scale, metres, if fitted.
    pub terminal_position_m: Option<f32>,
    /// Axial force from a load cell, newtons (positive = compressive load the
    /// cylinder pushes against), if fitted.
    pub load_cell_force_n: Option<f32>,
    /// Home switch, closed = true, if one is wired.
    pub home_switch: Option<bool>,
    /// Power-stage (heat-sink) temperature, °C, if measured.
    pub power_stage_temperature_c: Option<f32>,
}

impl SensorSample {
    /// A sample with zero currents, the given bus voltage and no optional
    /// sensors.
    pub const fn idle(bus_voltage_v: f32) -> Self {
        Self {
            phase_current_a: [0.0; 3],
            encoder_count: 0,
            bus_voltage_v,
            terminal_position_m: None,
            load_cell_force_n: None,
            home_switch: None,
            power_stage_temperature_c: None,
        }
    }
}

/// What the core asks of the power stage for the next PWM period.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PwmCommand {
    /// High-side duty cycle of phases a, b, c, each in [0, 1].
    pub duty: [f32; 3],
    /// False: all six switches off (outputs disabled, motor coasts).
    pub enable: bool,
    /// True: energise the holding brake's coil (brake open). The brake is
    /// spring-applied, so a dead board, a reset or `false` holds the rod.
    pub brake_release: bool,
}

impl PwmCommand {
    /// All switches off, brake applied. Duties sit at 50 % so re-enabling
    /// starts from zero average voltage.
    pub const OFF: Self = Self { duty: [0.5; 3], enable: false, brake_release: false };
}
