//! The current loop's interrupt: `ADC1_2` (ADC1 end of injected sequence),
//! once per PWM period, at the highest priority.
//!
//! Everything the interrupt needs is in one [`IsrState`], moved into it once
//! by `Board::new` before the interrupt is unmasked; from then on nothing
//! else touches it. Thread mode talks to it only through the link's atomics
//! (`board::link`). So the interrupt never waits, never takes a critical
//! section, never logs (defmt would take one), and nothing in thread mode can
//! delay it.
//!
//! One period:
//! 1. timing: cycle stamp, ticks since the valley (the sampling instant);
//! 2. acknowledge, read the five injected results and the encoder count;
//! 3. serve at most one request from thread mode (after the time-critical
//!    reads, before the step, so a command acts in this very period; a bulk
//!    request only before a step that runs the current loop alone);
//! 4. latch a hardware break; convert to SI; step the controller;
//! 5. CCR1..3 ← (1 − duty) × ARR, MOE per `enable` (never after a break:
//!    the flag is read again after MOE is set), brake release signal;
//! 6. overrun check; snapshot for thread mode every few periods;
//! 7. lock-free counters (`ISR_STATS`).

use core::sync::atomic::Ordering;

use cortex_m::peripheral::DWT;
use embassy_stm32::interrupt;
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals::Dir;
use servo_core::mailbox::Handoff;
use servo_core::{PwmCommand, SensorSample};

use super::super::link::{CalibrationSums, Envelope, IsrLink, IsrPhase, Reply, Request, Snapshot, SNAPSHOT_EVERY_PERIODS};
use super::super::{BoardStatus, ISR_STATS};
use super::{brake, cal, setup, MAX_DUTY, RECONSTRUCT_ABOVE_DUTY};

/// Everything the interrupt owns.
pub struct IsrState {
    link: IsrLink,
    phase: IsrPhase,
    arr: u16,
    period_cycles: u32,
    offset_codes: [f32; 3],
    calibration: CalibrationSums,
    /// Duties loaded at the latest valley (they shape the window after it)
    /// and at the one before (the window before it).
    duty_recent: [f32; 3],
    duty_older: [f32; 3],
    hw_trip: bool,
    hw_ocp_armed: bool,
    /// The bridge may be switched on at all: the comparator break passed its
    /// self-test and the option bytes keep the brake pin (BOOT0) from
    /// selecting the boot mode. False: every period ends with the bridge off
    /// whatever the controller asks (the controller holds the named fault).
    bridge_permitted: bool,
    bus_voltage_v: f32,
    temperature_c: f32,
    last_entry_cycles: u32,
    have_last_entry: bool,
    brake: brake::ReleaseSignal,
    /// The release signal of the latest period (what the feedback must show).
    brake_release_commanded: bool,
    brake_feedback: brake::FeedbackWatch,
    /// The feedback fault as last reported to the controller.
    brake_feedback_fault: bool,
    periods_to_snapshot: u32,
    /// A bulk request taken in a period with a speed or position tick,
    /// served in the next one (which runs the current loop only).
    deferred: Option<Envelope<Request>>,
}

static STATE: Handoff<IsrState> = Handoff::new();

/// Moves the interrupt's state in place (once; `Err` gives it back).
pub fn install(state: IsrState) -> Result<(), IsrState> {
    STATE.put(state)
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

impl IsrState {
    pub fn new(link: IsrLink, arr: u16, period_cycles: u32, hw_ocp_armed: bool, boot_safe: bool) -> Self {
        Self {
            link,
            phase: IsrPhase::Idle,
            arr,
            period_cycles,
            offset_codes: [cal::CURRENT_OFFSET_NOMINAL_CODE; 3],
            calibration: CalibrationSums { sum: [0; 3], count: 0, target: 0 },
            duty_recent: [0.5; 3],
            duty_older: [0.5; 3],
            hw_trip: false,
            hw_ocp_armed,
            bridge_permitted: hw_ocp_armed && boot_safe,
            bus_voltage_v: 0.0,
            temperature_c: 0.0,
            last_entry_cycles: 0,
            have_last_entry: false,
            brake: brake::ReleaseSignal::new(),
            brake_release_commanded: false,
            brake_feedback: brake::FeedbackWatch::new(),
            brake_feedback_fault: false,
            periods_to_snapshot: 0,
            deferred: None,
        }
    }

    /// Serves one request from thread mode.
    fn serve(&mut self, request: Request) -> Reply {
        match request {
            Request::BeginOffsetCalibration { samples } => {
                // Only with the bridge off (the offsets are zero-current
                // codes) and before the controller is installed (it would
                // not be stepped while the interrupt sums).
                if pac::TIM1.bdtr().read().moe() || self.link.controller().is_some() {
                    return Reply::Refused;
                }
                self.calibration = CalibrationSums { sum: [0; 3], count: 0, target: samples.max(1) };
                self.phase = IsrPhase::Calibrating;
                Reply::Done
            }
            Request::UseOffsets { offset_codes } => {
                let c = self.calibration;
                if self.phase != IsrPhase::Calibrating || c.count < c.target {
                    return Reply::Refused;
                }
                self.offset_codes = offset_codes;
                self.phase = IsrPhase::Running;
                Reply::Done
            }
            Request::ClearHardwareTrip => {
                if self.hw_trip && !setup::comparators_high() && !setup::supply_low() {
                    pac::TIM1.sr().modify(|w| {
                        w.set_bif(0, false);
                        w.set_sbif(false);
                    });
                    self.hw_trip = false;
                }
                Reply::HardwareTrip { cleared: !self.hw_trip }
            }
            Request::Drive(cmd) => match self.link.controller() {
                Some(c) => Reply::Drive(c.command(cmd)),
                None => Reply::NoDrive,
            },
            Request::ReadParams | Request::ApplyParams | Request::Bulk => self.link.serve_bulk(request),
        }
    }

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
        // `math::max`, a compare: `f32::max` is a call to libm's `fmaxf`
        // in an image built for size.
        use servo_core::math::max;
        let [d0, d1, d2] = [max(r0, p0), max(r1, p1), max(r2, p2)];
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
            // The ESC1 wires no home-switch input: homing runs to the hard
            // stop (`control.homing.method`).
            home_switch: None,
            power_stage_temperature_c: Some(self.temperature_c),
        }
    }

    /// Latches the hardware break (which already cleared MOE) and tells the
    /// controller, so its loops stop pushing against a dead bridge and the
    /// operator sees why (bridge off, brake applied).
    fn latch_break(&mut self) {
        self.hw_trip = true;
        if let Some(c) = self.link.controller() {
            c.report_bridge_break();
        }
    }

    /// Writes the command to TIM1 and the brake pin. Duties go to the
    /// preload registers and take effect at the next valley; MOE acts at once.
    fn apply(&mut self, cmd: PwmCommand) {
        let t = pac::TIM1;
        let [a, b, c] = cmd.duty;
        let finite = a.is_finite() && b.is_finite() && c.is_finite();
        if cmd.enable && !finite {
            ISR_STATS.bad_duty.fetch_add(1, Ordering::Relaxed);
        }
        let moe = t.bdtr().read().moe();
        let bridge_on = cmd.enable && finite && !self.hw_trip && self.bridge_permitted;
        if bridge_on {
            let arr = self.arr as f32;
            // PWM mode 2: the high side is on while CNT ≥ CCR.
            let ccr = |d: f32| (servo_core::math::round((1.0 - servo_core::math::clamp(d, 0.0, MAX_DUTY)) * arr)) as u16;
            t.ccr(0).write(|w| w.set_ccr(ccr(a)));
            t.ccr(1).write(|w| w.set_ccr(ccr(b)));
            t.ccr(2).write(|w| w.set_ccr(ccr(c)));
            if !moe {
                t.bdtr().modify(|w| w.set_moe(true));
                // The break race: a comparator pulse that came after the
                // flag was read at the top of this period cleared MOE in
                // hardware (so `moe` read false), and the write above set it
                // again. Read the flag after the write: once the break has
                // fired, the bridge stays off (for the few cycles between the
                // two writes at most, never for the rest of the period).
                if break_flag() {
                    t.bdtr().modify(|w| w.set_moe(false));
                    self.latch_break();
                }
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
        // Board interlock: the brake opens only while the bridge drives the
        // motor (a hardware break or a bad duty closes it in the same period).
        self.brake_release_commanded = cmd.brake_release && bridge_on && !self.hw_trip;
        self.brake.drive(self.brake_release_commanded);
    }

    /// The brake's feedback against the command: a disagreement longer
    /// than the brake takes to move latches `BRAKE_FEEDBACK` (a controlled
    /// stop: the bridge holds the load); agreement again lets it clear.
    fn watch_brake_feedback(&mut self) {
        let verdict = self.brake_feedback.update(self.brake_release_commanded, brake::feedback_released());
        let fault = match verdict {
            brake::FeedbackVerdict::Agrees => false,
            brake::FeedbackVerdict::Settling => return,
            brake::FeedbackVerdict::Disagrees => true,
        };
        if fault != self.brake_feedback_fault {
            self.brake_feedback_fault = fault;
            if let Some(c) = self.link.controller() {
                c.report_board_condition(servo_core::protection::FaultSet::BRAKE_FEEDBACK, fault);
            }
        }
    }

    fn snapshot(&self) -> Snapshot {
        Snapshot {
            seq: 0,
            phase: self.phase,
            calibration: self.calibration,
            offset_codes: self.offset_codes,
            status: BoardStatus {
                bus_voltage_v: self.bus_voltage_v,
                temperature_c: self.temperature_c,
                hw_overcurrent_armed: self.hw_ocp_armed,
                hw_overcurrent_tripped: self.hw_trip,
            },
            ..Snapshot::INITIAL
        }
    }
}

/// Whether TIM1's break fired: the comparators (BIF) or the system break
/// (SBIF: lockup, flash ECC, SRAM parity, supply monitor). Both stay set
/// until software clears them.
#[inline(always)]
fn break_flag() -> bool {
    let sr = pac::TIM1.sr().read();
    sr.bif(0) || sr.sbif()
}

#[interrupt]
fn ADC1_2() {
    // The state, claimed from the hand-off on the first entry (cortex-m-rt
    // makes this `static mut` a `&mut` local to the handler).
    static mut OWNED: Option<&'static mut IsrState> = None;

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
    setup::clear_injected_flags();
    let raw = Raw {
        i_u: adc1.jdr(0).read().jdata(),
        i_w: adc1.jdr(1).read().jdata(),
        ntc: adc1.jdr(2).read().jdata(),
        i_v: adc2.jdr(0).read().jdata(),
        vbus: adc2.jdr(1).read().jdata(),
    };
    let encoder_count = pac::TIM4.cnt().read().cnt();
    let break_fired = break_flag();

    if OWNED.is_none() {
        *OWNED = STATE.claim();
    }
    let Some(s) = OWNED.as_deref_mut() else {
        // Cannot happen (installed before the interrupt is unmasked); stay safe.
        tim1.bdtr().modify(|w| w.set_moe(false));
        brake::force_closed();
        ISR_STATS.busy.fetch_add(1, Ordering::Relaxed);
        return;
    };

    let mut overrun = s.have_last_entry && t0.wrapping_sub(s.last_entry_cycles) > s.period_cycles + s.period_cycles / 2;
    s.last_entry_cycles = t0;
    s.have_last_entry = true;

    // A bulk request (a parameter set, a capture or test-signal request:
    // a few hundred bytes of copies and the controller's work) waits for a
    // period that runs the current loop only and ends no capture batch: in
    // a speed or position period, or beside a capture's end, it would
    // lengthen the longest period (docs/cost.md, *Worst period*). The wait
    // is at most two periods; thread mode allows four.
    let request = match s.deferred.take() {
        Some(r) => Some(r),
        None => s.link.take_request(),
    };
    let served = request.and_then(|request| {
        let bulk = matches!(request.body, Request::ReadParams | Request::ApplyParams | Request::Bulk);
        if bulk && !s.link.controller().is_none_or(|c| c.next_period_serves_bulk()) {
            s.deferred = Some(request);
            return None;
        }
        let reply = s.serve(request.body);
        s.link.reply(request.seq, reply);
        Some(())
    });

    if break_fired && !s.hw_trip {
        s.latch_break();
    }
    s.bus_voltage_v = raw.vbus as f32 * cal::VBUS_VOLTS_PER_CODE;
    s.temperature_c = cal::NTC_T0_C + (raw.ntc as f32 * cal::VOLTS_PER_CODE - cal::NTC_V_AT_T0) / cal::NTC_V_PER_C;

    let cmd = match s.phase {
        IsrPhase::Idle => PwmCommand::OFF,
        IsrPhase::Calibrating => {
            let c = &mut s.calibration;
            if c.count < c.target {
                let [a, b, w] = c.sum;
                c.sum = [
                    a.wrapping_add(raw.i_u as u32),
                    b.wrapping_add(raw.i_v as u32),
                    w.wrapping_add(raw.i_w as u32),
                ];
                c.count += 1;
            }
            PwmCommand::OFF
        }
        IsrPhase::Running => {
            let mut sample = s.sample(raw, encoder_count);
            match s.link.controller() {
                Some(c) => {
                    // What the core's own calibration (`Command::Calibrate`)
                    // found on top of the codes measured at start-up.
                    let [a, b, cc] = c.current_offsets_a();
                    sample.phase_current_a[0] -= a;
                    sample.phase_current_a[1] -= b;
                    sample.phase_current_a[2] -= cc;
                    // Out of line: compiled with the core's speed settings,
                    // not this image's size settings (see the method).
                    c.step_out_of_line(&sample)
                }
                None => PwmCommand::OFF,
            }
        }
    };
    s.apply(cmd);
    if brake::FEEDBACK_FITTED {
        s.watch_brake_feedback();
    }

    // A newer sequence already complete: this step came too late for it.
    if adc1.isr().read().jeos() {
        overrun = true;
    }
    // A flash erase or write (thread mode, bridge off) stalls instruction
    // fetch, so this interrupt misses periods: expected, not an overrun.
    if overrun && !super::super::FLASH_STALL.load(Ordering::Relaxed) {
        if let Some(c) = s.link.controller() {
            c.report_isr_overrun();
        }
    }

    // Snapshot for thread mode: every few periods, and at once after a
    // request so the caller sees its effect.
    if served.is_some() || s.periods_to_snapshot == 0 {
        s.periods_to_snapshot = SNAPSHOT_EVERY_PERIODS;
        let snapshot = s.snapshot();
        s.link.publish(snapshot);
    }
    s.periods_to_snapshot -= 1;

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
