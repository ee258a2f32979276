//! ST B-G431B-ESC1 (STM32G431CBU6, L6387E gate drivers, STL180N6F7 MOSFETs,
//! three 3 mΩ low-side shunts amplified by the MCU's own OPAMP1/2/3).
//!
//! Hardware facts come from the board's user manual (UM2516) and ST's Motor
//! Control SDK configuration for this board (MC Workbench "B-G431B-ESC1"
//! power/control board): pin map, shunt network gain 9.14, VBUS divider
//! 0.0963, NTC 1.4 V at 25 °C and 19 mV/°C, comparator overcurrent trip.
//!
//! | function                 | pin / resource                                   |
//! |--------------------------|--------------------------------------------------|
//! | PWM U/V/W high side      | PA8 / PA9 / PA10 = TIM1_CH1/2/3 (AF6)            |
//! | PWM U/V/W low side       | PC13 (AF4) / PA12 (AF6) / PB15 (AF4) = CH1N/2N/3N|
//! | shunt U: + / − / amp out | PA1 OPAMP1_VINP0 / PA3 VINM0 / PA2 → ADC1_IN3    |
//! | shunt V: + / − / amp out | PA7 OPAMP2_VINP0 / PA5 VINM0 / PA6 → ADC2_IN3    |
//! | shunt W: + / − / amp out | PB0 OPAMP3_VINP0 / PB2 VINM0 / PB1 → ADC1_IN12   |
//! | bus voltage              | PA0 → ADC2_IN1 (ADC12_IN1)                       |
//! | power-stage NTC          | PB14 → ADC1_IN5                                  |
//! | encoder A / B (Hall H1/H2)| PB6 / PB7 = TIM4_CH1/CH2 (AF2), x4 quadrature   |
//! | LED / button             | PC6 / PC10 (active low)                          |
//! | holding-brake driver     | PB8 (Hall H3 / encoder Z pad, free with A/B): high = coil on, brake open |
//! | overcurrent              | COMP1/2/4 (+: PA1/PA7/PB0, −: DAC3) → TIM1 BRK   |
//!
//! The ESC1 has no external break pin wired; its overcurrent protection is
//! internal: the comparators watch the shunt amplifier inputs against a DAC3
//! threshold and drive TIM1's break input, which clears MOE in hardware
//! within the break filter time (no software in the path).
//!
//! # Timing
//!
//! TIM1 counts up and down (centre-aligned mode 1) at 170 MHz, ARR = 4250 for
//! 20 kHz. Channels 1–3 use PWM mode 2: the high side conducts around the
//! counter *peak*, the low sides (and so the shunts) around the *valley*. The
//! repetition counter (RCR = 1, phase-locked at start-up) makes the update
//! event happen only at the valley; TRGO2 = update starts the ADC injected
//! sequences there, exactly in the middle of the low-side conduction, and
//! the same update loads the preloaded CCRs, so every PWM pulse is symmetric
//! and a duty computed from the sample at valley k acts from valley k+1.
//! (Why not CH4: the update event already sits where the shunts conduct, and
//! it is also the instant the preloaded duties change; one event, no second
//! compare to keep aligned.)
//!
//! ADC1 and ADC2 run on the synchronous clock HCLK/4 = 42.5 MHz (no trigger
//! jitter). ADC1: I_U (6.5 cycles), I_W (6.5), NTC (47.5); ADC2: I_V (6.5),
//! VBUS (47.5). I_U and I_V are sampled together at the valley, I_W 0.45 µs
//! later; ADC1 ends last, at ≈ 2.3 µs, and its end-of-injected-sequence
//! interrupt (`ADC1_2`, priority 0, the highest) runs the control step.

use core::cell::RefCell;
use core::sync::atomic::Ordering;

use cortex_m::peripheral::DWT;
use critical_section::Mutex;
use embassy_stm32::gpio::{Flex, Input, Level, Output, OutputType, Pull, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::pac;
use embassy_stm32::pac::adc::vals::{Adcaldif, Exten, SampleTime};
use embassy_stm32::pac::adccommon::vals::Ckmode;
use embassy_stm32::pac::comp::vals::{Blanking, Hysteresis, Inm, Polarity};
use embassy_stm32::pac::opamp::vals::{PgaGain, VmSel, VpSel};
use embassy_stm32::pac::timer::vals::{Bkinp, Bkp, Cms, Dir, FilterValue, Mms2, Ocm, Ossi, Ossr};
use embassy_stm32::peripherals::{ADC1, ADC2, COMP1, COMP2, COMP4, DAC3, OPAMP1, OPAMP2, OPAMP3, TIM1, TIM4};
use embassy_stm32::rcc;
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::complementary_pwm::ComplementaryPwmPin;
use embassy_stm32::timer::qei::{self, Qei, QeiMode};
use embassy_stm32::timer::simple_pwm::{PwmPin, PwmPinConfig};
use embassy_stm32::timer::{Ch1, Ch2, Ch3};
use embassy_stm32::{Peri, Peripherals};
use servo_core::{ControlParams, PwmCommand, SensorSample};

use super::{BoardStatus, Calibration, ServoBoard, ISR_STATS};

/// Shown in the boot banner.
pub const NAME: &str = "B-G431B-ESC1 (STM32G431CB)";

/// The parameter set this board runs: the ESC1 takes at most a 6S (25.2 V)
/// pack, so the 24 V bench variant of the drive.
pub const PARAMS: ControlParams = ControlParams::BENCH_24V;

/// Board calibration: every constant that turns a raw code into SI units, in
/// one place. Sources: UM2516 schematic and ST MCSDK's B-G431B-ESC1 power
/// board description.
pub mod cal {
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
}

/// Dead time between one switch of a leg turning off and the other turning
/// on. The L6387E has interlocking but inserts no dead time, so TIM1 does.
/// Turn-off of an STL180N6F7 through the L6387E (≈ 105 ns propagation plus a
/// ≈ 120 nC gate discharged at ≈ 0.65 A, ≈ 200 ns) is ≈ 300 ns; 500 ns keeps
/// ≈ 200 ns margin while costing 1 % of the 50 µs period (≈ 0.25 V of
/// average voltage error at 24 V near current zero crossings). ST's MCSDK
/// ships 750–800 ns for this board: raise it if the gate waveforms of a
/// particular board show any overlap.
pub const DEAD_TIME_NS: u32 = 500;

/// Above this duty (in the period that contains the sample), a phase's
/// low-side window around the valley is shorter than the ≈ 1 µs ringing
/// after switching, so its shunt reading is replaced by −(sum of the other
/// two). Cheap form of the MCSDK's per-sector choice of two shunts.
pub const RECONSTRUCT_ABOVE_DUTY: f32 = 0.90;

/// Largest high-side duty written to the timer. The L6387E high-side supply
/// is a bootstrap capacitor recharged while the low side conducts: keep at
/// least 1 µs of low-side time per period (2 % of 50 µs). The core's
/// modulation limit (0.95 of the linear range → duty ≤ 0.975) stays below it.
pub const MAX_DUTY: f32 = 0.98;

/// Turn the comparator break on (recommended; a self-test at start-up turns
/// it off, with an error in the log, if a comparator is already high).
pub const HW_OVERCURRENT_BREAK: bool = true;

/// Clock tree: 8 MHz crystal, PLL ×85/2/2 → 170 MHz SYSCLK = HCLK = PCLK1/2,
/// range-1 boost (needed above 150 MHz).
pub fn clock_config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::{Hse, HseMode, Pll, PllMul, PllPreDiv, PllRDiv, PllSource, Sysclk};
    let mut config = embassy_stm32::Config::default();
    config.rcc.hse = Some(Hse { freq: Hertz(8_000_000), mode: HseMode::Oscillator });
    config.rcc.pll = Some(Pll {
        source: PllSource::HSE,
        prediv: PllPreDiv::DIV2,
        mul: PllMul::MUL85,
        divp: None,
        divq: None,
        divr: Some(PllRDiv::DIV2),
    });
    config.rcc.sys = Sysclk::PLL1_R;
    config.rcc.boost = true;
    // Nothing here uses DMA; keep its vectors below the PWM interrupt anyway.
    config.bdma_interrupt_priority = Priority::P2;
    config
}

/// What the board clamped in the parameter set.
#[derive(Clone, Copy, Debug, Default, PartialEq, defmt::Format)]
pub struct BoardLimitsApplied {
    pub bus_overvoltage_v: Option<f32>,
    pub current_max_a: Option<f32>,
    pub overcurrent_trip_a: Option<f32>,
}

/// Lowers (never raises) the limits of `params` to what this power stage
/// survives, and says what it lowered. `const`, so the firmware's set is
/// lowered and then validated at compile time: a set made for a higher bus
/// than the board's may become invalid (undervoltage above overvoltage), and
/// the build then fails naming the field.
pub const fn apply_board_limits(params: ControlParams) -> (ControlParams, BoardLimitsApplied) {
    // NaN counts as "above": it is replaced by the board's rating.
    const fn lower(value: f32, max: f32) -> (f32, Option<f32>) {
        if value > max || value.is_nan() { (max, Some(max)) } else { (value, None) }
    }
    let mut p = params;
    let (bus_ov, bus_overvoltage_v) = lower(p.faults.bus_overvoltage_v, cal::BOARD_MAX_BUS_V);
    let (i_max, current_max_a) = lower(p.limits.current_max_a, cal::BOARD_MAX_CURRENT_A);
    let (ocp, overcurrent_trip_a) = lower(p.faults.overcurrent_trip_a, cal::HW_OCP_TRIP_A);
    p.faults.bus_overvoltage_v = bus_ov;
    p.limits.current_max_a = i_max;
    p.faults.overcurrent_trip_a = ocp;
    (p, BoardLimitsApplied { bus_overvoltage_v, current_max_a, overcurrent_trip_a })
}

/// Why the board could not be brought up. The bridge stays off in every case.
#[derive(Clone, Copy, Debug, PartialEq, defmt::Format)]
pub enum BoardError {
    /// The PWM frequency gives an auto-reload outside 1000..=65535 or off by
    /// more than 0.1 %.
    PwmFrequency { requested_hz: f32 },
    /// The dead time does not fit TIM1's DTG encoding.
    DeadTime,
    /// An ADC did not finish calibration / become ready in time.
    AdcStartup { adc: u8 },
    /// The update event could not be locked to the counter valley.
    PwmPhaseLock,
}

// ADC channel numbers (RM0440 / device pin table), see the table above.
const ADC1_CH_I_U: u8 = 3; // PA2, OPAMP1 output
const ADC1_CH_I_W: u8 = 12; // PB1, OPAMP3 output
const ADC1_CH_NTC: u8 = 5; // PB14
const ADC2_CH_I_V: u8 = 3; // PA6, OPAMP2 output
const ADC2_CH_VBUS: u8 = 1; // PA0
/// JEXTSEL for TIM1_TRGO2 on ADC1/2 (RM0440, injected trigger table).
const JEXTSEL_TIM1_TRGO2: u8 = 8;

/// What the interrupt does with a sample.
#[derive(Clone, Copy, PartialEq)]
enum IsrMode {
    /// Bridge off, nothing converted (before the offset calibration).
    Idle,
    /// Bridge off, summing raw current codes.
    Calibrating,
    /// Converting and stepping the controller.
    Running,
}

/// Board state owned by the interrupt (the main task touches it only inside
/// short critical sections).
struct IsrCtx {
    mode: IsrMode,
    arr: u16,
    period_cycles: u32,
    offset_codes: [f32; 3],
    cal_sum: [u32; 3],
    cal_count: u32,
    cal_target: u32,
    /// Duties loaded at the latest valley (they shape the window after it)
    /// and at the one before (the window before it).
    duty_recent: [f32; 3],
    duty_older: [f32; 3],
    hw_trip: bool,
    hw_ocp_armed: bool,
    bus_voltage_v: f32,
    temperature_c: f32,
    last_entry_cycles: u32,
    have_last_entry: bool,
}

static CTX: Mutex<RefCell<IsrCtx>> = Mutex::new(RefCell::new(IsrCtx {
    mode: IsrMode::Idle,
    arr: 0,
    period_cycles: 0,
    offset_codes: [cal::CURRENT_OFFSET_NOMINAL_CODE; 3],
    cal_sum: [0; 3],
    cal_count: 0,
    cal_target: 0,
    duty_recent: [0.5; 3],
    duty_older: [0.5; 3],
    hw_trip: false,
    hw_ocp_armed: false,
    bus_voltage_v: 0.0,
    temperature_c: 0.0,
    last_entry_cycles: 0,
    have_last_entry: false,
}));

/// The peripherals and pins this board module owns. Dropping it would hand
/// pins back to embassy; `main` keeps it for ever.
pub struct Board {
    _tim1: Peri<'static, TIM1>,
    _adcs: (Peri<'static, ADC1>, Peri<'static, ADC2>),
    _opamps: (Peri<'static, OPAMP1>, Peri<'static, OPAMP2>, Peri<'static, OPAMP3>),
    _comps: (Peri<'static, COMP1>, Peri<'static, COMP2>, Peri<'static, COMP4>),
    _dac3: Peri<'static, DAC3>,
    _pwm_high: (PwmPin<'static, TIM1, Ch1>, PwmPin<'static, TIM1, Ch2>, PwmPin<'static, TIM1, Ch3>),
    _pwm_low: (
        ComplementaryPwmPin<'static, TIM1, Ch1>,
        ComplementaryPwmPin<'static, TIM1, Ch2>,
        ComplementaryPwmPin<'static, TIM1, Ch3>,
    ),
    _analog: [Flex<'static>; 11],
    _encoder: Qei<'static, TIM4>,
    led: Output<'static>,
    /// Written from the ISR through BSRR (atomic); kept here so the pin
    /// stays configured as an output.
    _brake: Output<'static>,
    button: Input<'static>,
    cpu_hz: u32,
    pwm_timer_hz: u32,
}

impl Board {
    /// Brings the power stage up with the bridge off: PWM running at 50 %
    /// with MOE clear (all six switches held off by OSSI), ADC armed on the
    /// PWM valley, encoder counting, and the `ADC1_2` interrupt unmasked at
    /// the highest priority (it keeps the bridge off until a controller is
    /// installed and the current offsets are known).
    ///
    /// Needs the DWT cycle counter running (main enables it) for the
    /// interrupt timing figures.
    pub fn new(p: Peripherals, pwm_frequency_hz: f32) -> Result<Self, BoardError> {
        let hclk_hz = rcc::clocks(&p.RCC).hclk1.to_hertz().map(|h| h.0).unwrap_or(170_000_000);
        let tim_hz = rcc::frequency::<TIM1>().0;

        // Halting the core in the debugger stops TIM1 and disables its
        // outputs (as if MOE were cleared): a breakpoint never leaves a
        // duty cycle frozen on the motor.
        pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));

        // --- PWM outputs: pulled down so the gate driver inputs sit low
        // whenever the timer does not drive them.
        let out = PwmPinConfig { output_type: OutputType::PushPull, speed: Speed::VeryHigh, pull: Pull::Down };
        let pwm_high = (
            PwmPin::new_with_config(p.PA8, out),
            PwmPin::new_with_config(p.PA9, out),
            PwmPin::new_with_config(p.PA10, out),
        );
        let pwm_low = (
            ComplementaryPwmPin::new_with_config(p.PC13, out),
            ComplementaryPwmPin::new_with_config(p.PA12, out),
            ComplementaryPwmPin::new_with_config(p.PB15, out),
        );

        let arr = pwm_auto_reload(tim_hz, pwm_frequency_hz)?;
        let dtg = dead_time_dtg(DEAD_TIME_NS, tim_hz).ok_or(BoardError::DeadTime)?;
        // The timer clock is HCLK over a whole APB ratio (1, 2, ...): the
        // CPU cycles per PWM period need no 64-bit division (that alone
        // would link 0.9 KB of runtime).
        let period_cycles = 2 * u32::from(arr) * (hclk_hz / tim_hz).max(1);

        // --- Analog pins: shunt inputs, gain pins, amplifier outputs, VBUS, NTC.
        let mut analog = [
            Flex::new(p.PA0),
            Flex::new(p.PA1),
            Flex::new(p.PA2),
            Flex::new(p.PA3),
            Flex::new(p.PA5),
            Flex::new(p.PA6),
            Flex::new(p.PA7),
            Flex::new(p.PB0),
            Flex::new(p.PB1),
            Flex::new(p.PB2),
            Flex::new(p.PB14),
        ];
        for pin in analog.iter_mut() {
            pin.set_as_analog();
        }

        setup_opamps();
        let hw_ocp_armed = if HW_OVERCURRENT_BREAK { setup_overcurrent_comparators() } else { false };
        setup_tim1(arr, dtg, hw_ocp_armed);
        setup_adcs()?;

        critical_section::with(|cs| {
            let mut ctx = CTX.borrow_ref_mut(cs);
            ctx.arr = arr;
            ctx.period_cycles = period_cycles;
            ctx.hw_ocp_armed = hw_ocp_armed;
            ctx.mode = IsrMode::Idle;
        });

        start_tim1_locked_to_valley(arr)?;

        // Arm both injected sequences; the first trigger is the next valley.
        pac::ADC1.cr().modify(|w| w.set_jadstart(true));
        pac::ADC2.cr().modify(|w| w.set_jadstart(true));

        // --- Encoder: TIM4 x4 quadrature on PB6/PB7, free-running 16 bits.
        let qei_config = qei::Config {
            ch1_pull: Pull::Up,
            ch2_pull: Pull::Up,
            mode: QeiMode::Mode3,
            auto_reload: u16::MAX,
        };
        let encoder = Qei::new(p.TIM4, p.PB6, p.PB7, qei_config);
        // 8-sample digital filter at 170 MHz (47 ns): rejects ringing on a
        // cable, passes the 500 kHz edge rate of 10 000 counts/rev at 3000 rpm.
        pac::TIM4.ccmr_input(0).modify(|w| {
            w.set_icf(0, FilterValue::FCK_INT_N8);
            w.set_icf(1, FilterValue::FCK_INT_N8);
        });

        let led = Output::new(p.PC6, Level::Low, Speed::Low);
        // Low at reset and here: the spring-applied brake holds until the
        // core asks for it open (an external low-side switch drives the coil).
        let brake = Output::new(p.PB8, Level::Low, Speed::Low);
        let button = Input::new(p.PC10, Pull::Up);

        // The time driver (TIM2) and anything else stay below the PWM interrupt.
        interrupt::TIM2.set_priority(Priority::P4);
        interrupt::ADC1_2.set_priority(Priority::P0);
        interrupt::ADC1_2.unpend();
        // SAFETY: the handler below only touches state built above.
        unsafe { interrupt::ADC1_2.enable() };

        Ok(Self {
            _tim1: p.TIM1,
            _adcs: (p.ADC1, p.ADC2),
            _opamps: (p.OPAMP1, p.OPAMP2, p.OPAMP3),
            _comps: (p.COMP1, p.COMP2, p.COMP4),
            _dac3: p.DAC3,
            _pwm_high: pwm_high,
            _pwm_low: pwm_low,
            _analog: analog,
            _encoder: encoder,
            led,
            _brake: brake,
            button,
            cpu_hz: hclk_hz,
            pwm_timer_hz: tim_hz,
        })
    }

    /// PWM timer ticks per second (for converting the latency figure).
    pub fn pwm_timer_hz(&self) -> u32 {
        self.pwm_timer_hz
    }

    /// Core clock, i.e. DWT cycles per second.
    pub fn cpu_hz(&self) -> u32 {
        self.cpu_hz
    }
}

impl ServoBoard for Board {
    fn begin_offset_calibration(&mut self, samples: u32) {
        critical_section::with(|cs| {
            let mut ctx = CTX.borrow_ref_mut(cs);
            ctx.cal_sum = [0; 3];
            ctx.cal_count = 0;
            ctx.cal_target = samples.max(1);
            ctx.mode = IsrMode::Calibrating;
        });
    }

    fn offset_calibration(&mut self) -> Calibration {
        critical_section::with(|cs| {
            let mut ctx = CTX.borrow_ref_mut(cs);
            match ctx.mode {
                IsrMode::Calibrating if ctx.cal_count < ctx.cal_target => Calibration::Pending,
                IsrMode::Calibrating => {
                    let n = ctx.cal_count as f32;
                    let [a, b, c] = ctx.cal_sum;
                    let offsets = [a as f32 / n, b as f32 / n, c as f32 / n];
                    let plausible = offsets.iter().all(|o| {
                        (o - cal::CURRENT_OFFSET_NOMINAL_CODE).abs() <= cal::CURRENT_OFFSET_TOLERANCE_CODE
                    });
                    if plausible {
                        ctx.offset_codes = offsets;
                        ctx.mode = IsrMode::Running;
                        Calibration::Done { offset_codes: offsets }
                    } else {
                        ctx.mode = IsrMode::Idle;
                        Calibration::Failed { offset_codes: offsets }
                    }
                }
                IsrMode::Running => Calibration::Done { offset_codes: ctx.offset_codes },
                IsrMode::Idle => Calibration::Failed { offset_codes: ctx.offset_codes },
            }
        })
    }

    fn status(&self) -> BoardStatus {
        critical_section::with(|cs| {
            let ctx = CTX.borrow_ref(cs);
            BoardStatus {
                bus_voltage_v: ctx.bus_voltage_v,
                temperature_c: ctx.temperature_c,
                hw_overcurrent_armed: ctx.hw_ocp_armed,
                hw_overcurrent_tripped: ctx.hw_trip,
            }
        })
    }

    fn clear_latched_faults(&mut self) -> bool {
        critical_section::with(|cs| {
            let mut ctx = CTX.borrow_ref_mut(cs);
            if !ctx.hw_trip {
                return true;
            }
            if comparators_high() {
                return false;
            }
            pac::TIM1.sr().modify(|w| w.set_bif(0, false));
            ctx.hw_trip = false;
            true
        })
    }

    fn set_led(&mut self, on: bool) {
        self.led.set_level(if on { Level::High } else { Level::Low });
    }

    fn button_pressed(&self) -> bool {
        self.button.is_low()
    }
}

/// ARR for centre-aligned PWM at `pwm_hz` from a `tim_hz` counter clock.
fn pwm_auto_reload(tim_hz: u32, pwm_hz: f32) -> Result<u16, BoardError> {
    let err = BoardError::PwmFrequency { requested_hz: pwm_hz };
    if !pwm_hz.is_finite() || pwm_hz <= 0.0 {
        return Err(err);
    }
    let arr = libm::roundf(tim_hz as f32 / (2.0 * pwm_hz));
    if !(1000.0..=65535.0).contains(&arr) {
        return Err(err);
    }
    let actual = tim_hz as f32 / (2.0 * arr);
    if ((actual - pwm_hz) / pwm_hz).abs() > 1e-3 {
        return Err(err);
    }
    Ok(arr as u16)
}

/// TIM1 BDTR.DTG for at least `ns` of dead time at `tdts_hz` (CKD = 1).
fn dead_time_dtg(ns: u32, tdts_hz: u32) -> Option<u8> {
    // Round up: never shorter than asked.
    let ticks = (ns as u64 * tdts_hz as u64).div_ceil(1_000_000_000);
    match ticks {
        0..=127 => Some(ticks as u8),
        128..=254 => Some(0b1000_0000 | (ticks.div_ceil(2) - 64) as u8),
        255..=504 => Some(0b1100_0000 | (ticks.div_ceil(8) - 32) as u8),
        505..=1008 => Some(0b1110_0000 | (ticks.div_ceil(16) - 32) as u8),
        _ => None,
    }
}

/// OPAMP1/2/3 as non-inverting PGA ×16 with the gain network's ground on
/// VINM0 (the shunt's Kelvin return), output on the pin (ADC reads it there).
fn setup_opamps() {
    for opamp in [pac::OPAMP1, pac::OPAMP2, pac::OPAMP3] {
        opamp.csr().write(|w| {
            w.set_vp_sel(VpSel::VINP0);
            w.set_vm_sel(VmSel::PGA);
            w.set_pga_gain(PgaGain::GAIN16_INPUT_VINM0);
            w.set_opahsm(false); // normal mode, as ST's configuration for this board
            w.set_opaintoen(false);
            w.set_usertrim(false);
            w.set_opampen(true);
        });
    }
}

/// DAC3 (internal only) sets the trip level; COMP1/2/4 compare the shunt
/// amplifier inputs PA1/PA7/PB0 with it. Returns whether the break may be
/// armed: a comparator that is already high with the bridge off means the
/// threshold or the front end is not what this module assumes.
fn setup_overcurrent_comparators() -> bool {
    rcc::enable_and_reset::<DAC3>();
    let dac = pac::DAC3;
    dac.mcr().write(|w| {
        w.set_mode(0, pac::dac::vals::Mode::NORMAL_INT_BUFDIS);
        w.set_mode(1, pac::dac::vals::Mode::NORMAL_INT_BUFDIS);
        w.set_hfsel(0b10); // AHB above 160 MHz
    });
    dac.cr().write(|w| {
        w.set_en(0, true);
        w.set_en(1, true);
    });
    for _ in 0..10_000 {
        let sr = dac.sr().read();
        if sr.dacrdy(0) && sr.dacrdy(1) {
            break;
        }
    }
    dac.dhr12r(0).write(|w| w.set_dhr(cal::HW_OCP_DAC_CODE));
    dac.dhr12r(1).write(|w| w.set_dhr(cal::HW_OCP_DAC_CODE));

    // INMSEL 100: COMP1 ← DAC3_CH1, COMP2/COMP4 ← DAC3_CH2. INPSEL 0:
    // COMP1 ← PA1, COMP2 ← PA7, COMP4 ← PB0.
    for comp in [pac::COMP1, pac::COMP2, pac::COMP4] {
        comp.csr().write(|w| {
            w.set_inmsel(Inm::DACA);
            w.set_inpsel(false);
            w.set_polarity(Polarity::NOT_INVERTED);
            w.set_hyst(Hysteresis::HYST10M);
            w.set_blanksel(Blanking::NO_BLANKING);
            w.set_en(true);
        });
    }
    // Comparator start-up is a few µs.
    embassy_time::block_for(embassy_time::Duration::from_micros(50));
    !comparators_high()
}

fn comparators_high() -> bool {
    pac::COMP1.csr().read().value() || pac::COMP2.csr().read().value() || pac::COMP4.csr().read().value()
}

/// TIM1: centre-aligned, PWM mode 2 on CH1–3 with complementary outputs and
/// dead time, preloaded CCRs at 50 %, TRGO2 = update, outputs held off
/// (MOE = 0, OSSI/OSSR = idle level, idle level low on all six), comparator
/// break armed. The counter is not started here.
fn setup_tim1(arr: u16, dtg: u8, hw_ocp_armed: bool) {
    rcc::enable_and_reset::<TIM1>();
    let t = pac::TIM1;
    t.cr1().write(|w| {
        w.set_cms(Cms::CENTER_ALIGNED1);
        w.set_arpe(true);
    });
    t.psc().write_value(0);
    t.arr().write(|w| w.set_arr(arr));
    t.rcr().write(|w| w.set_rep(0));
    t.ccmr_output(0).write(|w| {
        w.set_ocm(0, Ocm::PWM_MODE2);
        w.set_ocpe(0, true);
        w.set_ocm(1, Ocm::PWM_MODE2);
        w.set_ocpe(1, true);
    });
    t.ccmr_output(1).write(|w| {
        w.set_ocm(0, Ocm::PWM_MODE2);
        w.set_ocpe(0, true);
    });
    let half = arr / 2;
    t.ccr(0).write(|w| w.set_ccr(half));
    t.ccr(1).write(|w| w.set_ccr(half));
    t.ccr(2).write(|w| w.set_ccr(half));
    t.ccer().write(|w| {
        for ch in 0..3 {
            w.set_cce(ch, true);
            w.set_ccne(ch, true);
        }
    });
    // Idle levels (OISx/OISxN) stay 0: with MOE = 0 every switch is off.
    t.cr2().write(|w| w.set_mms2(Mms2::UPDATE));
    t.af1().write(|w| {
        w.set_bkine(false);
        w.set_bkcmpe(0, hw_ocp_armed);
        w.set_bkcmpe(1, hw_ocp_armed);
        w.set_bkcmpe(3, hw_ocp_armed);
        w.set_bkcmpp(0, Bkinp::NOT_INVERTED);
        w.set_bkcmpp(1, Bkinp::NOT_INVERTED);
        w.set_bkcmpp(3, Bkinp::NOT_INVERTED);
    });
    t.bdtr().write(|w| {
        w.set_dtg(dtg);
        w.set_ossi(Ossi::IDLE_LEVEL);
        w.set_ossr(Ossr::IDLE_LEVEL);
        w.set_bke(0, hw_ocp_armed);
        w.set_bkp(0, Bkp::ACTIVE_HIGH);
        w.set_bkf(0, FilterValue::FCK_INT_N8);
        w.set_aoe(false);
        w.set_moe(false);
    });
    // A Cortex-M4 lockup also breaks TIM1.
    pac::SYSCFG.cfgr2().modify(|w| w.set_cll(true));
    // Load ARR, CCRs and RCR into the shadow registers.
    t.egr().write(|w| w.set_ug(true));
    t.sr().write_value(pac::timer::regs::SrAdv(0));
}

/// Starts TIM1 and locks the update event (and so the ADC trigger and the
/// CCR reload) to the counter valley. With RCR = 1 an update happens every
/// second turn-around, at the one where RCR was reloaded: so RCR goes from 0
/// to 1 while the counter runs down, and the next valley reloads it.
fn start_tim1_locked_to_valley(arr: u16) -> Result<(), BoardError> {
    let t = pac::TIM1;
    t.cr1().modify(|w| w.set_cen(true));
    let locked = critical_section::with(|_| {
        // Wait for the first half of a down-count (≥ 12 µs before the valley).
        let mut ready = false;
        for _ in 0..100_000 {
            let dir = t.cr1().read().dir();
            let cnt = t.cnt().read().cnt();
            if dir == Dir::DOWN && cnt > arr / 2 {
                ready = true;
                break;
            }
        }
        if !ready {
            return false;
        }
        t.rcr().write(|w| w.set_rep(1));
        // Check two update events: both must come at the valley.
        for _ in 0..2 {
            t.sr().modify(|w| w.set_uif(false));
            let mut seen = false;
            for _ in 0..100_000 {
                if t.sr().read().uif() {
                    seen = true;
                    break;
                }
            }
            if !seen || t.cr1().read().dir() != Dir::UP {
                return false;
            }
        }
        true
    });
    if locked {
        Ok(())
    } else {
        Err(BoardError::PwmPhaseLock)
    }
}

/// ADC1 and ADC2: synchronous clock HCLK/4, calibrated, injected sequences
/// triggered by TIM1_TRGO2 rising edge, end-of-sequence interrupt on ADC1.
fn setup_adcs() -> Result<(), BoardError> {
    rcc::enable_and_reset::<ADC1>();
    rcc::enable_and_reset::<ADC2>();
    pac::ADC12_COMMON.ccr().modify(|w| w.set_ckmode(Ckmode::SYNC_DIV4));

    for (index, adc) in [(1u8, pac::ADC1), (2u8, pac::ADC2)] {
        // Leave deep power-down, then start the regulator (t_ADCVREG_STUP = 20 µs).
        adc.cr().write(|w| w.set_deeppwd(false));
        adc.cr().write(|w| w.set_advregen(true));
        embassy_time::block_for(embassy_time::Duration::from_micros(30));
        // Single-ended calibration.
        adc.cr().modify(|w| {
            w.set_adcaldif(Adcaldif::SINGLE_ENDED);
            w.set_adcal(true);
        });
        if !wait_until(|| !adc.cr().read().adcal()) {
            return Err(BoardError::AdcStartup { adc: index });
        }
        embassy_time::block_for(embassy_time::Duration::from_micros(1));
        adc.isr().write(|w| w.set_adrdy(true));
        adc.cr().modify(|w| w.set_aden(true));
        if !wait_until(|| adc.isr().read().adrdy()) {
            return Err(BoardError::AdcStartup { adc: index });
        }
        // 12-bit, right aligned, no regular conversions, injected queue off.
        adc.cfgr().modify(|w| {
            w.set_jqdis(true);
            w.set_jauto(false);
            w.set_jdiscen(false);
        });
    }

    let adc1 = pac::ADC1;
    adc1.smpr().modify(|w| {
        w.set_smp(ADC1_CH_I_U as usize, SampleTime::CYCLES6_5);
        w.set_smp(ADC1_CH_NTC as usize, SampleTime::CYCLES47_5);
    });
    adc1.smpr2().modify(|w| w.set_smp(ADC1_CH_I_W as usize - 10, SampleTime::CYCLES6_5));
    adc1.jsqr().write(|w| {
        w.set_jl(2); // three conversions
        w.set_jextsel(JEXTSEL_TIM1_TRGO2);
        w.set_jexten(Exten::RISING_EDGE);
        w.set_jsq(0, ADC1_CH_I_U);
        w.set_jsq(1, ADC1_CH_I_W);
        w.set_jsq(2, ADC1_CH_NTC);
    });

    let adc2 = pac::ADC2;
    adc2.smpr().modify(|w| {
        w.set_smp(ADC2_CH_I_V as usize, SampleTime::CYCLES6_5);
        w.set_smp(ADC2_CH_VBUS as usize, SampleTime::CYCLES47_5);
    });
    adc2.jsqr().write(|w| {
        w.set_jl(1); // two conversions
        w.set_jextsel(JEXTSEL_TIM1_TRGO2);
        w.set_jexten(Exten::RISING_EDGE);
        w.set_jsq(0, ADC2_CH_I_V);
        w.set_jsq(1, ADC2_CH_VBUS);
    });

    // ADC1 ends last (longer sequence, same trigger): its JEOS runs the loop.
    adc1.isr().write(|w| {
        w.set_jeos(true);
        w.set_jeoc(true);
    });
    adc2.isr().write(|w| {
        w.set_jeos(true);
        w.set_jeoc(true);
    });
    adc1.ier().write(|w| w.set_jeosie(true));
    Ok(())
}

fn wait_until(mut done: impl FnMut() -> bool) -> bool {
    for _ in 0..1_000_000 {
        if done() {
            return true;
        }
    }
    false
}

/// Raw codes of one injected round.
#[derive(Clone, Copy)]
struct Raw {
    i_u: u16,
    i_v: u16,
    i_w: u16,
    vbus: u16,
    ntc: u16,
}

impl IsrCtx {
    fn sample(&self, raw: Raw, encoder_count: u16) -> SensorSample {
        let [o_u, o_v, o_w] = self.offset_codes;
        let mut i = [
            (raw.i_u as f32 - o_u) * cal::AMPS_PER_CODE,
            (raw.i_v as f32 - o_v) * cal::AMPS_PER_CODE,
            (raw.i_w as f32 - o_w) * cal::AMPS_PER_CODE,
        ];
        // The phase with the shortest low-side window is rebuilt from the
        // other two (Kirchhoff: the three currents sum to zero).
        let [r0, r1, r2] = self.duty_recent;
        let [p0, p1, p2] = self.duty_older;
        let d = [r0.max(p0), r1.max(p1), r2.max(p2)];
        let [d0, d1, d2] = d;
        let [a, b, c] = i;
        if d0 >= d1 && d0 >= d2 && d0 > RECONSTRUCT_ABOVE_DUTY {
            i = [-(b + c), b, c];
        } else if d1 >= d2 && d1 > RECONSTRUCT_ABOVE_DUTY {
            i = [a, -(a + c), c];
        } else if d2 > RECONSTRUCT_ABOVE_DUTY {
            i = [a, b, -(a + b)];
        }
        SensorSample {
            phase_current_a: i,
            encoder_count,
            bus_voltage_v: self.bus_voltage_v,
            terminal_position_m: None,
            load_cell_force_n: None,
        }
    }

    /// Writes the command to TIM1. Duties go to the preload registers and
    /// take effect at the next valley; MOE acts at once.
    fn apply(&mut self, cmd: PwmCommand) {
        let t = pac::TIM1;
        pac::GPIOB.bsrr().write(|w| {
            if cmd.brake_release {
                w.set_bs(8, true)
            } else {
                w.set_br(8, true)
            }
        });
        let [a, b, c] = cmd.duty;
        let finite = a.is_finite() && b.is_finite() && c.is_finite();
        if cmd.enable && !finite {
            ISR_STATS.bad_duty.fetch_add(1, Ordering::Relaxed);
        }
        let moe = t.bdtr().read().moe();
        if cmd.enable && finite && !self.hw_trip {
            let arr = self.arr as f32;
            // PWM mode 2: the high side is on while CNT ≥ CCR.
            let ccr = |d: f32| (servo_core::math::round((1.0 - servo_core::math::clamp(d, 0.0, MAX_DUTY)) * arr)) as u16;
            t.ccr(0).write(|w| w.set_ccr(ccr(a)));
            t.ccr(1).write(|w| w.set_ccr(ccr(b)));
            t.ccr(2).write(|w| w.set_ccr(ccr(c)));
            if !moe {
                t.bdtr().modify(|w| w.set_moe(true));
            }
            self.duty_older = self.duty_recent;
            self.duty_recent = [a, b, c];
        } else {
            if moe {
                t.bdtr().modify(|w| w.set_moe(false));
            }
            let half = self.arr / 2;
            t.ccr(0).write(|w| w.set_ccr(half));
            t.ccr(1).write(|w| w.set_ccr(half));
            t.ccr(2).write(|w| w.set_ccr(half));
            self.duty_older = [0.5; 3];
            self.duty_recent = [0.5; 3];
        }
    }
}

/// The current loop: ADC1 end of injected sequence, once per PWM period.
///
/// 1. timing: cycle stamp, ticks since the valley (the sampling instant);
/// 2. acknowledge, read the five injected results and the encoder count;
/// 3. latch a hardware break; convert to SI; `Controller::step`;
/// 4. CCR1..3 ← (1 − duty) × ARR, MOE per `enable`;
/// 5. overrun check (a newer sequence already finished, or a period was
///    skipped) → count, and the controller latches `isr_overrun`.
#[interrupt]
fn ADC1_2() {
    let t0 = DWT::cycle_count();
    let tim1 = pac::TIM1;
    let cnt = tim1.cnt().read().cnt() as u32;
    let counting_up = tim1.cr1().read().dir() == Dir::UP;
    let arr = tim1.arr().read().arr() as u32;
    let latency_ticks = if counting_up { cnt } else { 2 * arr - cnt.min(arr) };

    let adc1 = pac::ADC1;
    let adc2 = pac::ADC2;
    if !adc1.isr().read().jeos() {
        return;
    }
    adc1.isr().write(|w| {
        w.set_jeos(true);
        w.set_jeoc(true);
    });
    adc2.isr().write(|w| {
        w.set_jeos(true);
        w.set_jeoc(true);
    });
    let raw = Raw {
        i_u: adc1.jdr(0).read().jdata(),
        i_w: adc1.jdr(1).read().jdata(),
        ntc: adc1.jdr(2).read().jdata(),
        i_v: adc2.jdr(0).read().jdata(),
        vbus: adc2.jdr(1).read().jdata(),
    };
    let encoder_count = pac::TIM4.cnt().read().cnt();
    let break_fired = tim1.sr().read().bif(0);

    let mut overrun = false;
    critical_section::with(|cs| {
        let Ok(mut ctx) = CTX.borrow(cs).try_borrow_mut() else {
            // Cannot happen (one core, highest priority); stay safe anyway.
            tim1.bdtr().modify(|w| w.set_moe(false));
            ISR_STATS.busy.fetch_add(1, Ordering::Relaxed);
            return;
        };
        if ctx.have_last_entry && t0.wrapping_sub(ctx.last_entry_cycles) > ctx.period_cycles + ctx.period_cycles / 2 {
            overrun = true;
        }
        ctx.last_entry_cycles = t0;
        ctx.have_last_entry = true;
        if break_fired && !ctx.hw_trip {
            // Hardware already cleared MOE; the controller latches the trip
            // (bridge off, brake applied) so its loops stop pushing against a
            // dead bridge and the operator sees why.
            ctx.hw_trip = true;
            super::report_bridge_break(cs);
        }
        ctx.bus_voltage_v = raw.vbus as f32 * cal::VBUS_VOLTS_PER_CODE;
        ctx.temperature_c =
            cal::NTC_T0_C + (raw.ntc as f32 * cal::VOLTS_PER_CODE - cal::NTC_V_AT_T0) / cal::NTC_V_PER_C;

        let cmd = match ctx.mode {
            IsrMode::Idle => PwmCommand::OFF,
            IsrMode::Calibrating => {
                if ctx.cal_count < ctx.cal_target {
                    let [a, b, c] = ctx.cal_sum;
                    ctx.cal_sum = [a + raw.i_u as u32, b + raw.i_v as u32, c + raw.i_w as u32];
                    ctx.cal_count += 1;
                }
                PwmCommand::OFF
            }
            IsrMode::Running => {
                let sample = ctx.sample(raw, encoder_count);
                super::control_period(cs, &sample)
            }
        };
        ctx.apply(cmd);

        // A newer sequence already complete: this step came too late for it.
        if adc1.isr().read().jeos() {
            overrun = true;
        }
        if overrun {
            super::report_overrun(cs);
        }
    });

    if overrun {
        ISR_STATS.overruns.fetch_add(1, Ordering::Relaxed);
    }
    if !counting_up {
        ISR_STATS.late.fetch_add(1, Ordering::Relaxed);
    }
    ISR_STATS.periods.fetch_add(1, Ordering::Relaxed);
    ISR_STATS.worst_latency_ticks.fetch_max(latency_ticks, Ordering::Relaxed);
    ISR_STATS.worst_cycles.fetch_max(DWT::cycle_count().wrapping_sub(t0), Ordering::Relaxed);
}
