//! Bring-up of the B-G431B-ESC1's peripherals, once, in thread mode, with
//! the bridge off: brake pin, PWM pins, analog pins, OPAMPs, DAC3 and the
//! comparators, TIM1, the ADCs' injected sequences, the encoder timer, the
//! interrupt priorities. Nothing here runs again after `Board::new` returns;
//! the interrupt's path is in `isr.rs`.

use embassy_stm32::gpio;
use embassy_stm32::pac::gpio::vals::{Moder, Ospeedr, Ot, Pupdr};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::pac;
use embassy_stm32::pac::adc::vals::{Adcaldif, Exten, SampleTime};
use embassy_stm32::pac::adccommon::vals::Ckmode;
use embassy_stm32::pac::comp::vals::{Blanking, Hysteresis, Inm, Polarity};
use embassy_stm32::pac::opamp::vals::{PgaGain, VmSel, VpSel};
use embassy_stm32::pac::timer::vals::{Bkinp, Bkp, CcmrInputCcs, Cms, Dir, FilterValue, Mms2, Ocm, Ossi, Ossr, Sms};
use embassy_stm32::peripherals::{ADC1, ADC2, DAC3, TIM1, TIM4};
use embassy_stm32::rcc;
use embassy_stm32::timer::{Ch1, Ch2, Ch3, TimerComplementaryPin, TimerPin};
use embassy_stm32::{Peri, Peripherals};

use super::super::link;
use super::{
    brake, cal, isr, Board, BoardError, ADC1_CH_I_U, ADC1_CH_I_W, ADC1_CH_NTC, ADC2_CH_I_V, ADC2_CH_VBUS,
    COMMS_IRQ_PRIORITY, DEAD_TIME_NS, JEXTSEL_TIM1_TRGO2, PWM_IRQ_PRIORITY, TIME_DRIVER_PRIORITY,
};

/// Puts every interrupt this image enables at its level: the PWM interrupt
/// alone at the top, the time driver below it. Safe to call before
/// `embassy_stm32::init` (which enables TIM2 without touching its priority),
/// and `main` does: from then on no interrupt but the PWM one sits at
/// priority 0, which the BASEPRI critical section relies on.
pub fn set_interrupt_priorities() {
    interrupt::TIM2.set_priority(TIME_DRIVER_PRIORITY);
    interrupt::ADC1_2.set_priority(PWM_IRQ_PRIORITY);
    // The transports (`comms`); their drivers enable them without setting
    // a priority, which would leave them at 0, level with the PWM interrupt.
    interrupt::USART2.set_priority(COMMS_IRQ_PRIORITY);
    interrupt::FDCAN1_IT0.set_priority(COMMS_IRQ_PRIORITY);
    interrupt::FDCAN1_IT1.set_priority(COMMS_IRQ_PRIORITY);
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
        // The brake pin first: driven low before anything that can take time
        // or fail (the driver is AC-coupled, so this is belt and braces).
        // `brake::Pin` names the same pin as `brake::PORT`/`PIN`: the type
        // annotation fails the build if the token here is another one.
        let brake_pin: Peri<'static, brake::Pin> = p.PB8;
        brake::configure_closed();
        brake::configure_feedback();

        let hclk_hz = rcc::clocks(&p.RCC).hclk1.to_hertz().map(|h| h.0).unwrap_or(170_000_000);
        let tim_hz = rcc::frequency::<TIM1>().0;

        // Halting the core in the debugger stops TIM1 and disables its
        // outputs (as if MOE were cleared): a breakpoint never leaves a
        // duty cycle frozen on the motor.
        pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));

        // --- Pins, from one table (one loop of register writes instead of a
        // driver object per pin): PWM outputs pulled down so the gate driver
        // inputs sit low whenever the timer does not drive them; shunt
        // inputs, gain pins, amplifier outputs, VBUS and NTC analog; the
        // encoder inputs pulled up; LED (low) and button (pulled up). The AF
        // numbers come from embassy's pin traits, so a pin that cannot carry
        // its signal fails the build.
        let pwm = |id: u8, af: u8| PinSetup::alternate(id, af, Pupdr::PULL_DOWN, Ospeedr::VERY_HIGH_SPEED);
        let analog = PinSetup::analog;
        let encoder = |id: u8, af: u8| PinSetup::alternate(id, af, Pupdr::PULL_UP, Ospeedr::LOW_SPEED);
        let pins = [
            pwm(p.PA8.id(), TimerPin::<TIM1, Ch1>::af_num(&*p.PA8)),
            pwm(p.PA9.id(), TimerPin::<TIM1, Ch2>::af_num(&*p.PA9)),
            pwm(p.PA10.id(), TimerPin::<TIM1, Ch3>::af_num(&*p.PA10)),
            pwm(p.PC13.id(), TimerComplementaryPin::<TIM1, Ch1>::af_num(&*p.PC13)),
            pwm(p.PA12.id(), TimerComplementaryPin::<TIM1, Ch2>::af_num(&*p.PA12)),
            pwm(p.PB15.id(), TimerComplementaryPin::<TIM1, Ch3>::af_num(&*p.PB15)),
            analog(p.PA0.id()),
            analog(p.PA1.id()),
            analog(p.PA2.id()),
            analog(p.PA3.id()),
            analog(p.PA5.id()),
            analog(p.PA6.id()),
            analog(p.PA7.id()),
            analog(p.PB0.id()),
            analog(p.PB1.id()),
            analog(p.PB2.id()),
            analog(p.PB14.id()),
            encoder(p.PB6.id(), TimerPin::<TIM4, Ch1>::af_num(&*p.PB6)),
            encoder(p.PB7.id(), TimerPin::<TIM4, Ch2>::af_num(&*p.PB7)),
            PinSetup { id: p.PC6.id(), moder: Moder::OUTPUT, af: 0, pupdr: Pupdr::FLOATING, ospeedr: Ospeedr::LOW_SPEED },
            PinSetup { id: p.PC10.id(), moder: Moder::INPUT, af: 0, pupdr: Pupdr::PULL_UP, ospeedr: Ospeedr::LOW_SPEED },
        ];
        configure_pins(&pins);

        let arr = pwm_auto_reload(tim_hz, pwm_frequency_hz)?;
        let dtg = dead_time_dtg(DEAD_TIME_NS, tim_hz).ok_or(BoardError::DeadTime)?;
        // The timer clock is HCLK over a whole APB ratio (1, 2, ...): the
        // CPU cycles per PWM period need no 64-bit division (that alone
        // would link 0.9 KB of runtime).
        let period_cycles = 2 * u32::from(arr) * (hclk_hz / tim_hz).max(1);

        setup_opamps();
        // A comparator already high with the bridge off fails the
        // self-test: the break is then not armed, and the interrupt keeps
        // the bridge off for good (`IsrState::apply`), the controller holding
        // the named fault.
        let hw_ocp_armed = setup_overcurrent_comparators();
        setup_supply_monitor();
        setup_tim1(arr, dtg, hw_ocp_armed);
        setup_adcs()?;

        start_tim1_locked_to_valley(arr)?;

        // Arm both injected sequences; the first trigger is the next valley.
        pac::ADC1.cr().modify(|w| w.set_jadstart(true));
        pac::ADC2.cr().modify(|w| w.set_jadstart(true));

        setup_encoder_timer();

        // The interrupt's state and its ends of the link, moved into it
        // before it is unmasked.
        let (thread_link, isr_link) = link::split().ok_or(BoardError::AlreadyUp)?;
        isr::install(isr::IsrState::new(isr_link, arr, period_cycles, hw_ocp_armed, brake::boot_pin_ignored())).map_err(|_| BoardError::AlreadyUp)?;

        set_interrupt_priorities();
        interrupt::ADC1_2.unpend();
        // SAFETY: the handler only touches the state installed above, the
        // link's atomics and the ADC/TIM1/TIM4/GPIO registers it owns.
        unsafe { interrupt::ADC1_2.enable() };

        Ok(Self {
            _tim1: p.TIM1,
            _adcs: (p.ADC1, p.ADC2),
            _opamps: (p.OPAMP1, p.OPAMP2, p.OPAMP3),
            _comps: (p.COMP1, p.COMP2, p.COMP4),
            _dac3: p.DAC3,
            _pins: [
                p.PA8.into(),
                p.PA9.into(),
                p.PA10.into(),
                p.PC13.into(),
                p.PA12.into(),
                p.PB15.into(),
                p.PA0.into(),
                p.PA1.into(),
                p.PA2.into(),
                p.PA3.into(),
                p.PA5.into(),
                p.PA6.into(),
                p.PA7.into(),
                p.PB0.into(),
                p.PB1.into(),
                p.PB2.into(),
                p.PB14.into(),
                p.PB6.into(),
                p.PB7.into(),
            ],
            _tim4: p.TIM4,
            led: p.PC6.into(),
            _brake: brake_pin,
            button: p.PC10.into(),
            link: thread_link,
            comms: Some(super::comms::CommsPeripherals {
                usart2: p.USART2,
                usart_tx: p.PB3,
                usart_rx: p.PB4,
                dma_tx: p.DMA1_CH1,
                dma_rx: p.DMA1_CH2,
                fdcan1: p.FDCAN1,
                can_rx: p.PA11,
                can_tx: p.PB9,
                can_shdn: p.PC11,
                can_term: p.PC14,
                flash: p.FLASH,
            }),
            cpu_hz: hclk_hz,
            pwm_timer_hz: tim_hz,
            period_cycles,
        })
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
    // Round up: never shorter than asked. In u32 (kHz × ns stays below 2³²
    // for any dead time the DTG field can hold): a u64 division would link
    // ≈ 0.9 KB of runtime in an image built for size.
    let ticks = ns.saturating_mul(tdts_hz.div_ceil(1000)).div_ceil(1_000_000);
    match ticks {
        0..=127 => Some(ticks as u8),
        128..=254 => Some(0b1000_0000 | (ticks.div_ceil(2) - 64) as u8),
        255..=504 => Some(0b1100_0000 | (ticks.div_ceil(8) - 32) as u8),
        505..=1008 => Some(0b1110_0000 | (ticks.div_ceil(16) - 32) as u8),
        _ => None,
    }
}

/// A GPIO's port and number as one byte, `port · 16 + pin` (embassy's
/// `AnyPin` numbering).
pub(super) trait PinId {
    fn id(&self) -> u8;
}

impl<P: gpio::Pin> PinId for P {
    fn id(&self) -> u8 {
        self.port() * 16 + self.pin()
    }
}

/// The register block of the GPIO port of pin `id` (ports are 1 KiB apart).
pub(super) fn gpio_port(id: u8) -> pac::gpio::Gpio {
    // SAFETY: GPIOA..GPIOG are 0x400 apart on the STM32G4 (RM0440 memory
    // map); the ids come from embassy's pin types.
    unsafe { pac::gpio::Gpio::from_ptr((pac::GPIOA.as_ptr() as usize + 0x400 * usize::from(id / 16)) as *mut ()) }
}

/// One pin's mode, alternate function, pull and speed (push-pull always).
#[derive(Clone, Copy)]
struct PinSetup {
    id: u8,
    moder: Moder,
    af: u8,
    pupdr: Pupdr,
    ospeedr: Ospeedr,
}

impl PinSetup {
    fn alternate(id: u8, af: u8, pupdr: Pupdr, ospeedr: Ospeedr) -> Self {
        Self { id, moder: Moder::ALTERNATE, af, pupdr, ospeedr }
    }

    fn analog(id: u8) -> Self {
        Self { id, moder: Moder::ANALOG, af: 0, pupdr: Pupdr::FLOATING, ospeedr: Ospeedr::LOW_SPEED }
    }
}

/// Programs the pins, mode last (the function, pull and speed are in
/// place when the pin switches over; an output starts low).
#[inline(never)]
fn configure_pins(pins: &[PinSetup]) {
    for c in pins {
        let port = gpio_port(c.id);
        let n = usize::from(c.id % 16);
        port.bsrr().write(|w| w.set_br(n, true));
        port.afr(n / 8).modify(|w| w.set_afr(n % 8, c.af));
        port.otyper().modify(|w| w.set_ot(n, Ot::PUSH_PULL));
        port.ospeedr().modify(|w| w.set_ospeedr(n, c.ospeedr));
        port.pupdr().modify(|w| w.set_pupdr(n, c.pupdr));
        port.moder().modify(|w| w.set_moder(n, c.moder));
    }
}

/// TIM4: x4 quadrature (encoder mode 3) on CH1/CH2, free-running 16 bits,
/// 8-sample digital filter at 170 MHz (47 ns): rejects ringing on a cable,
/// passes the 500 kHz edge rate of 10 000 counts/rev at 3000 rpm.
fn setup_encoder_timer() {
    rcc::enable_and_reset::<TIM4>();
    let t = pac::TIM4;
    t.ccmr_input(0).modify(|w| {
        // CCxS = 01: ICx on TIx.
        w.set_ccs(0, CcmrInputCcs::TI4);
        w.set_ccs(1, CcmrInputCcs::TI4);
        w.set_icf(0, FilterValue::FCK_INT_N8);
        w.set_icf(1, FilterValue::FCK_INT_N8);
    });
    t.ccer().modify(|w| {
        w.set_cce(0, true);
        w.set_cce(1, true);
        w.set_ccp(0, false);
        w.set_ccp(1, false);
    });
    t.smcr().modify(|w| w.set_sms(Sms::ENCODER_MODE_3));
    t.arr().write(|w| w.set_arr(u16::MAX.into()));
    t.cr1().modify(|w| w.set_cen(true));
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

pub(super) fn comparators_high() -> bool {
    pac::COMP1.csr().read().value() || pac::COMP2.csr().read().value() || pac::COMP4.csr().read().value()
}

/// The supply monitor (PVD) at its 2.9 V threshold (PLS = 110, RM0440:
/// falling edge ≈ 2.8 V): the ESC1's 3.3 V rail sagging that far means the
/// gate drivers' logic inputs and the ADC reference are no longer what the
/// loop assumes. Locked to TIM1's break in `setup_tim1`.
fn setup_supply_monitor() {
    // PWR's clock (embassy's `init` enables it for the boost mode; no
    // reset here, which would undo that).
    pac::RCC.apb1enr1().modify(|w| w.set_pwren(true));
    pac::RCC.apb2enr().modify(|w| w.set_syscfgen(true));
    pac::PWR.cr2().modify(|w| {
        w.set_pls(0b110);
        w.set_pvde(true);
    });
}

/// Whether the supply monitor sees the 3.3 V rail below its threshold now.
pub(super) fn supply_low() -> bool {
    pac::PWR.sr2().read().pvdo()
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
        // The break input on in every case (the system break above acts
        // through it); the comparators feed it only if their self-test passed.
        w.set_bke(0, true);
        w.set_bkp(0, Bkp::ACTIVE_HIGH);
        w.set_bkf(0, FilterValue::FCK_INT_N8);
        w.set_aoe(false);
        w.set_moe(false);
    });
    // The system break: a core lockup, a flash double-ECC error, an SRAM
    // parity error and the supply monitor (PVD, `setup_supply_monitor`)
    // clear MOE in hardware, like the comparators (RM0440, SYSCFG_CFGR2;
    // the lock bits hold until reset). They set SR.SBIF besides BIF.
    pac::SYSCFG.cfgr2().modify(|w| {
        w.set_cll(true);
        w.set_eccl(true);
        w.set_spl(true);
        w.set_pvdl(true);
    });
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
    clear_injected_flags();
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

/// Acknowledges both ADCs' injected end-of-conversion and end-of-sequence
/// flags (write 1 to clear): at set-up, and every period in the interrupt.
/// Two plain writes: a loop over the two ADCs becomes an iterator call per
/// ADC in an image built for size.
#[inline(always)]
pub(super) fn clear_injected_flags() {
    let flags = {
        let mut w = pac::adc::regs::Isr(0);
        w.set_jeos(true);
        w.set_jeoc(true);
        w
    };
    pac::ADC1.isr().write_value(flags);
    pac::ADC2.isr().write_value(flags);
}
