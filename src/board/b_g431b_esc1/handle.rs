//! [`Board`]: what thread mode holds once the board is up, and how it asks
//! the interrupt for things (through `board::link`, never a critical
//! section).

use embassy_stm32::gpio::{AnyPin, Pin};
use embassy_stm32::pac::gpio::vals::Idr;
use embassy_stm32::peripherals::{ADC1, ADC2, COMP1, COMP2, COMP4, DAC3, OPAMP1, OPAMP2, OPAMP3, TIM1, TIM4};
use embassy_stm32::Peri;

use super::super::link::{IsrPhase, LinkError, Reply, Request, Snapshot, ThreadLink};
use super::super::{BoardStatus, Calibration, ServoBoard};
use super::setup::{self, PinId};
use super::{brake, cal};

/// How many PWM periods a request may take before `call` gives up. The
/// interrupt answers in the period after the request is posted, so 1–2;
/// 4 leaves margin for a period that runs long, and is still only 200 µs.
const CALL_TIMEOUT_PERIODS: u32 = 4;

/// The peripherals and pins this board module owns. Dropping it would hand
/// pins back to embassy; `main` keeps it for ever.
pub struct Board {
    pub(super) _tim1: Peri<'static, TIM1>,
    pub(super) _adcs: (Peri<'static, ADC1>, Peri<'static, ADC2>),
    pub(super) _opamps: (Peri<'static, OPAMP1>, Peri<'static, OPAMP2>, Peri<'static, OPAMP3>),
    pub(super) _comps: (Peri<'static, COMP1>, Peri<'static, COMP2>, Peri<'static, COMP4>),
    pub(super) _dac3: Peri<'static, DAC3>,
    /// PWM outputs, analog inputs, encoder inputs (`setup::configure_pins`
    /// programmed them); held so embassy never hands them to anyone else.
    pub(super) _pins: [Peri<'static, AnyPin>; 19],
    pub(super) _tim4: Peri<'static, TIM4>,
    pub(super) led: Peri<'static, AnyPin>,
    /// Driven by the interrupt (BSRR) and the HardFault handler; held here
    /// so embassy never hands the pin to anyone else.
    pub(super) _brake: Peri<'static, brake::Pin>,
    pub(super) button: Peri<'static, AnyPin>,
    pub(super) link: ThreadLink,
    /// USART2, FDCAN1 and the flash, set aside for `main` (`take_comms`).
    pub(super) comms: Option<super::comms::CommsPeripherals>,
    pub(super) cpu_hz: u32,
    pub(super) pwm_timer_hz: u32,
    /// CPU cycles per PWM period.
    pub(super) period_cycles: u32,
}

impl Board {
    /// PWM timer ticks per second (for converting the latency figure).
    pub fn pwm_timer_hz(&self) -> u32 {
        self.pwm_timer_hz
    }

    /// The transports' and the store's peripherals, once.
    pub fn take_comms(&mut self) -> Option<super::comms::CommsPeripherals> {
        self.comms.take()
    }

    /// Core clock, i.e. DWT cycles per second.
    pub fn cpu_hz(&self) -> u32 {
        self.cpu_hz
    }
}

impl ServoBoard for Board {
    fn call(&mut self, request: Request) -> Result<Reply, LinkError> {
        self.link.call(request, self.period_cycles.saturating_mul(CALL_TIMEOUT_PERIODS))
    }

    fn snapshot(&mut self) -> Snapshot {
        self.link.snapshot()
    }

    fn begin_offset_calibration(&mut self, samples: u32) -> Result<(), LinkError> {
        match self.call(Request::BeginOffsetCalibration { samples })? {
            Reply::Done => Ok(()),
            // Refused: the bridge is on, offsets cannot be measured now.
            _ => Err(LinkError::Refused),
        }
    }

    fn offset_calibration(&mut self) -> Calibration {
        let s = self.snapshot();
        match s.phase {
            IsrPhase::Running => Calibration::Done { offset_codes: s.offset_codes },
            IsrPhase::Idle => Calibration::Failed { offset_codes: s.offset_codes },
            IsrPhase::Calibrating if s.calibration.count < s.calibration.target => Calibration::Pending,
            IsrPhase::Calibrating => {
                let n = s.calibration.count as f32;
                let [a, b, c] = s.calibration.sum;
                let offsets = [a as f32 / n, b as f32 / n, c as f32 / n];
                let plausible = offsets
                    .iter()
                    .all(|o| (o - cal::CURRENT_OFFSET_NOMINAL_CODE).abs() <= cal::CURRENT_OFFSET_TOLERANCE_CODE);
                if !plausible {
                    // The interrupt stays in calibration: bridge off for good.
                    return Calibration::Failed { offset_codes: offsets };
                }
                match self.call(Request::UseOffsets { offset_codes: offsets }) {
                    Ok(Reply::Done) => Calibration::Done { offset_codes: offsets },
                    // Not taken this time: ask again on the next poll.
                    _ => Calibration::Pending,
                }
            }
        }
    }

    fn status(&mut self) -> BoardStatus {
        self.snapshot().status
    }

    fn clear_latched_faults(&mut self) -> bool {
        matches!(self.call(Request::ClearHardwareTrip), Ok(Reply::HardwareTrip { cleared: true }))
    }

    fn read_params(&mut self) -> Result<servo_core::ControlParams, LinkError> {
        self.link.read_params(self.period_cycles.saturating_mul(CALL_TIMEOUT_PERIODS))
    }

    fn apply_params(
        &mut self,
        params: &servo_core::params::ValidatedParams,
    ) -> Result<Result<(), servo_core::controller::ApplyError>, LinkError> {
        self.link.apply_params(params, self.period_cycles.saturating_mul(CALL_TIMEOUT_PERIODS))
    }

    fn bulk(&mut self, payload: crate::board::link::BulkIn) -> Result<crate::board::link::BulkOut, LinkError> {
        self.link.bulk(payload, self.period_cycles.saturating_mul(CALL_TIMEOUT_PERIODS))
    }

    fn set_led(&mut self, on: bool) {
        let n = usize::from(self.led.pin());
        setup::gpio_port(self.led.id()).bsrr().write(|w| if on { w.set_bs(n, true) } else { w.set_br(n, true) });
    }

    fn rating(&self) -> servo_core::params::PowerStageRating {
        super::RATING
    }

    fn button_pressed(&self) -> bool {
        setup::gpio_port(self.button.id()).idr().read().idr(usize::from(self.button.pin())) == Idr::LOW
    }
}
