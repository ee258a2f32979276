//! Firmware image: the servo drive on an STM32G4 board (B-G431B-ESC1).
//!
//! Two contexts:
//! - the PWM interrupt (`board::active`, highest priority, 20 kHz) converts
//!   the ADC/encoder sample and calls `Controller::step` — the whole control
//!   law runs there;
//! - this main task (embassy executor, thread mode, lowest priority) brings
//!   the board up, calibrates the current offsets, installs the controller,
//!   aligns and enables the drive, then logs telemetry, a heartbeat and
//!   handles the button.
//!
//! See docs/firmware.md for pins, timing, flashing and reading the log.

#![no_std]
#![no_main]

mod board;

use board::active as hw;
use board::{with_controller, Calibration, ServoBoard, ISR_STATS};
use cortex_m_rt::{exception, ExceptionFrame};
use defmt::{error, info, warn};
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_stm32::pac;
use embassy_time::{Duration, Instant, Ticker, Timer};
use panic_probe as _;
use servo_core::{Command, Controller, Mode};

/// Telemetry records per second over RTT. A `Telemetry` frame is ≈ 90 bytes
/// of defmt (17 floats, mode, options, fault names as indices), so 50 Hz is
/// ≈ 4.5 kB/s: well inside what an ST-LINK/V2-1 polls through probe-rs, and
/// the 1 KiB RTT buffer still holds ≈ 0.2 s if the host stalls. Each frame
/// also masks interrupts while defmt-rtt copies it (a few µs), which delays
/// the PWM interrupt by that much: few, short frames keep that jitter rare.
/// 50 Hz follows position moves (100 ms scale); it does not resolve the
/// current or speed loops — use the host simulator for those.
const TELEMETRY_HZ: u64 = 50;
/// One heartbeat line every this many telemetry ticks (1 Hz).
const HEARTBEAT_EVERY: u32 = TELEMETRY_HZ as u32;
/// Independent watchdog timeout: five telemetry periods. The main task feeds
/// it only while the current-loop ISR keeps running.
const WATCHDOG_TIMEOUT_MS: u32 = 100;
/// Zero-current samples averaged per phase at start-up (≈ 0.1 s at 20 kHz).
const OFFSET_CALIBRATION_SAMPLES: u32 = 2048;
/// Find the electrical offset at start-up (incremental encoders lose it at
/// every power-up). The rotor moves to a pole position.
const ALIGN_AT_STARTUP: bool = true;
/// Enable after alignment and hold the position found there.
const ENABLE_AT_STARTUP: bool = true;
/// Demo: after enabling, move back and forth between these two motor-side
/// positions (metres, inside the stroke), dwelling this long at each.
const DEMO_MOTION: Option<([f32; 2], Duration)> = None;

#[embassy_executor::main]
async fn main(_spawner: Spawner) {
    let p = embassy_stm32::init(hw::clock_config());
    info!("cylinder-servo {} on {}", env!("CARGO_PKG_VERSION"), hw::NAME);
    let watchdog_reset = board::watchdog::take_reset_cause();
    if watchdog_reset {
        error!("the last reset came from the independent watchdog");
    }

    // DWT cycle counter for the interrupt timing figures.
    if let Some(mut cp) = cortex_m::Peripherals::take() {
        cp.DCB.enable_trace();
        cp.DWT.enable_cycle_counter();
    } else {
        warn!("core peripherals already taken: ISR cycle figures will read 0");
    }

    let params = *board::VALID_PARAMS.get();
    let mut board = match board::bring_up(p) {
        Ok(b) => b,
        Err(e) => {
            error!("board bring-up failed: {} (bridge off)", e);
            park().await
        }
    };
    let pwm_timer_hz = board.pwm_timer_hz();
    info!(
        "PWM {=f32} Hz centre-aligned, dead time {=u32} ns, HW overcurrent break: {}",
        params.rates.pwm_frequency_hz,
        hw::DEAD_TIME_NS,
        board.status().hw_overcurrent_armed
    );
    if !board.status().hw_overcurrent_armed && hw::HW_OVERCURRENT_BREAK {
        error!("a comparator was high with the bridge off: hardware overcurrent break NOT armed");
    }

    // Current offsets with the bridge off.
    board.begin_offset_calibration(OFFSET_CALIBRATION_SAMPLES);
    let offsets = loop {
        Timer::after_millis(10).await;
        match board.offset_calibration() {
            Calibration::Pending => {}
            Calibration::Done { offset_codes } => break offset_codes,
            Calibration::Failed { offset_codes } => {
                error!("current offsets implausible {} (codes): bridge stays off", offset_codes);
                park().await
            }
        }
    };
    info!("current offsets (ADC codes) U/V/W = {}", offsets);

    // Validated when the image was built (board::VALID_PARAMS).
    let mut controller = Controller::from_validated(board::VALID_PARAMS);
    if watchdog_reset {
        controller.report_watchdog_reset();
    }
    let faults = controller.faults();
    board::install_controller(controller);
    if !faults.is_empty() {
        error!("controller refuses to run: faults {}", faults);
    }

    if ALIGN_AT_STARTUP && faults.is_empty() {
        align().await;
    }
    if ENABLE_AT_STARTUP && faults.is_empty() {
        send(Command::Enable);
    }

    let mut ticker = Ticker::every(Duration::from_hz(TELEMETRY_HZ));
    // Fed below only while the ISR keeps running: 5 telemetry ticks of slack.
    board::watchdog::start(WATCHDOG_TIMEOUT_MS);
    let mut isr_periods_at_feed = ISR_STATS.snapshot().periods;
    let mut tick: u32 = 0;
    let mut button_was = false;
    let mut demo_leg = 0usize;
    let mut demo_dwell_until = Instant::now();
    loop {
        ticker.next().await;
        tick = tick.wrapping_add(1);
        let isr_periods = ISR_STATS.snapshot().periods;
        if isr_periods != isr_periods_at_feed {
            board::watchdog::feed();
            isr_periods_at_feed = isr_periods;
        }

        let snapshot = with_controller(|c| (c.telemetry(), c.mode(), c.move_in_progress()));
        let Some((telemetry, mode, moving)) = snapshot else {
            continue;
        };
        info!("tlm {}", telemetry);

        // Button: acknowledge faults, else toggle the bridge.
        let pressed = board.button_pressed();
        if pressed && !button_was {
            on_button(&mut board, mode);
        }
        button_was = pressed;

        if let Some((targets, dwell)) = DEMO_MOTION {
            if mode == Mode::Running && !moving && Instant::now() >= demo_dwell_until {
                let [a, b] = targets;
                let target = if demo_leg.is_multiple_of(2) { a } else { b };
                send(Command::MoveTo { position_m: target });
                demo_leg = demo_leg.wrapping_add(1);
                demo_dwell_until = Instant::now() + dwell;
            }
        }

        // LED: on = running, 1 Hz blink = disabled, 5 Hz blink = fault or
        // controlled stop (bridge on, holding).
        let led = match mode {
            Mode::Running | Mode::Aligning => true,
            Mode::Disabled => (tick / (TELEMETRY_HZ as u32 / 2)).is_multiple_of(2),
            Mode::Fault | Mode::Stopping | Mode::Braking => (tick / (TELEMETRY_HZ as u32 / 10)).is_multiple_of(2),
        };
        board.set_led(led);

        if tick.is_multiple_of(HEARTBEAT_EVERY) {
            let isr = ISR_STATS.snapshot();
            let status = board.status();
            let ns_per_cycle = 1.0e9 / board.cpu_hz() as f32;
            info!(
                "hb up={=u32}s mode={} faults={} bus={=f32}V temp={=f32}C hw_ocp_trip={=bool} isr: n={=u32} overruns={=u32} late={=u32} worst={=u32}cyc ({=f32}us) latency={=f32}us",
                tick / TELEMETRY_HZ as u32,
                mode,
                telemetry.faults,
                status.bus_voltage_v,
                status.temperature_c,
                status.hw_overcurrent_tripped,
                isr.periods,
                isr.overruns,
                isr.late,
                isr.worst_cycles,
                isr.worst_cycles as f32 * ns_per_cycle / 1000.0,
                isr.worst_latency_ticks as f32 * 1.0e6 / pwm_timer_hz as f32,
            );
        }
    }
}

/// Sends a command and logs a refusal.
fn send(cmd: Command) {
    match with_controller(|c| c.command(cmd)) {
        Some(Ok(outcome)) => info!("{} -> {}", cmd, outcome),
        Some(Err(e)) => warn!("{} refused: {}", cmd, e),
        None => warn!("{} dropped: no controller", cmd),
    }
}

/// Runs the alignment and waits for it to end (bounded).
async fn align() {
    send(Command::Align);
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        Timer::after_millis(20).await;
        match with_controller(|c| c.mode()) {
            Some(Mode::Aligning) if Instant::now() < deadline => {}
            Some(Mode::Aligning) => {
                warn!("alignment did not finish in 5 s; disabling");
                send(Command::Disable);
                return;
            }
            Some(mode) => {
                info!("alignment done, mode {}", mode);
                return;
            }
            None => return,
        }
    }
}

/// Button: first acknowledges whatever is latched (board trip, controller
/// faults); with nothing latched it toggles the bridge.
fn on_button(board: &mut hw::Board, mode: Mode) {
    let board_tripped = board.status().hw_overcurrent_tripped;
    if board_tripped {
        if board.clear_latched_faults() {
            info!("hardware overcurrent trip cleared");
        } else {
            warn!("hardware overcurrent still present: cannot clear");
        }
        return;
    }
    if mode == Mode::Fault {
        send(Command::ClearFaults);
    } else if mode == Mode::Running {
        send(Command::Disable);
    } else {
        send(Command::Enable);
    }
}

/// Stays here for ever, bridge off, still logging why.
async fn park() -> ! {
    loop {
        Timer::after_secs(5).await;
        error!("parked: see the first error above");
    }
}

/// Any fault (including a panic: panic-probe ends in `udf`) first switches
/// the bridge off, then stops. With a debugger attached, probe-rs halts on
/// the fault and the DBGMCU freeze already disabled the TIM1 outputs.
#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    pac::TIM1.bdtr().modify(|w| w.set_moe(false));
    loop {
        cortex_m::asm::nop();
    }
}
