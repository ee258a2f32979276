//! Firmware image: the servo drive on an STM32G4 board (B-G431B-ESC1).
//!
//! Two contexts:
//! - the PWM interrupt (`board::active`, priority 0, 20 kHz) converts the
//!   ADC/encoder sample and calls `Controller::step` — the whole control law
//!   runs there, on state the interrupt owns;
//! - this main task (embassy executor, thread mode) brings the board up,
//!   starts the watchdog, calibrates the current offsets, installs the
//!   controller (with the parameters saved in flash, if a valid record
//!   exists), and then serves the protocol on USART2 (ST-LINK virtual COM
//!   port) and FDCAN1 (the platform's setpoint stream), forwards the
//!   button, feeds the watchdog and logs telemetry.
//!
//! The two talk only through `board::link` (lock-free). Thread-mode critical
//! sections (embassy, defmt-rtt) mask by priority and never the PWM
//! interrupt (`masking`).
//!
//! Nothing moves at power-up: after any reset the drive waits for a command,
//! unless `control.startup.run_at_power_up` says otherwise.
//!
//! See docs/firmware.md for pins and reading the log, and the files it lists
//! for the power-up sequence, the brake, timing and flashing.

#![no_std]
#![no_main]

mod board;
mod hal_log;
mod masking;

use board::active as hw;
use board::drive::{BoardDrive, ParamsCache};
use board::link::{self, Reply, Request};
use board::{Calibration, ServoBoard, ISR_STATS};
use defmt::{error, info, warn};
use defmt_rtt as _;
use embassy_executor::Spawner;
use embassy_futures::select::{select4, Either4};
use embassy_stm32::pac;
use embassy_time::{Duration, Instant, Ticker, Timer};
use hal_log::{CanFault, UsartFault};
use hw::comms::{self, FlashStore};
use panic_probe as _;
use servo_core::params::{record, ValidatedParams};
use hw::can_stream::CanStream;
use servo_core::protocol::{self as proto, BootRecord, DriveFrame, FrameReader, ParamStore, RecordRejection, Server};
use servo_core::{Command, Controller, FaultSet, Mode};

/// Telemetry records per second over RTT. A `Telemetry` frame is ≈ 90 bytes
/// of defmt (17 floats, mode, options, fault names as indices), so 50 Hz is
/// ≈ 4.5 kB/s: well inside what an ST-LINK/V2-1 polls through probe-rs, and
/// the 1 KiB RTT buffer still holds ≈ 0.2 s if the host stalls (beyond that,
/// frames are dropped: defmt-rtt never blocks here). 50 Hz follows position
/// moves (100 ms scale); it does not resolve the current or speed loops —
/// use the host simulator for those.
const TELEMETRY_HZ: u64 = 50;
/// One heartbeat line every this many telemetry ticks (1 Hz).
const HEARTBEAT_EVERY: u32 = TELEMETRY_HZ as u32;
/// Independent watchdog timeout: five telemetry periods. Started before the
/// current offsets are measured, i.e. before the bridge can first be
/// enabled; fed from thread mode only while the PWM interrupt advances.
const WATCHDOG_TIMEOUT_MS: u32 = 100;
/// Zero-current samples averaged per phase at start-up (≈ 0.1 s at 20 kHz).
const OFFSET_CALIBRATION_SAMPLES: u32 = 2048;
/// Poll period while waiting at start-up (offsets, power-up steps): well
/// inside the watchdog timeout.
const STARTUP_POLL: Duration = Duration::from_millis(10);

/// Who the drive is, for `Info`.
const IDENTITY: proto::Identity = proto::Identity {
    firmware_version: env!("CARGO_PKG_VERSION"),
    git_hash: env!("GIT_HASH"),
    board: hw::NAME,
};

/// The image defaults `Defaults` restores, as a `static` (in flash): the
/// protocol server keeps a reference to them, not a 464-byte copy in the
/// main task's future (static RAM).
static DEFAULT_PARAMS: ValidatedParams = board::VALID_PARAMS;

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // `run` returns only to park: one `park` future in the task, not one
    // per way of failing (each inlined copy cost ≈ 120 bytes of flash).
    let dog = run(spawner).await;
    park(dog).await
}

/// Brings the drive up and then serves it for ever; returns only when the
/// start-up failed, with the watchdog if it runs already, to be parked.
async fn run(spawner: Spawner) -> Option<Watchdog> {
    // Priorities before `init` enables the time driver's interrupt: from the
    // first instant, nothing but the PWM interrupt sits at priority 0.
    hw::set_interrupt_priorities();
    let p = embassy_stm32::init(hw::clock_config());
    info!("cylinder-servo {} on {}", env!("CARGO_PKG_VERSION"), hw::NAME);
    let watchdog_reset = board::watchdog::take_reset_cause();
    if watchdog_reset {
        error!("the last reset came from the independent watchdog: waiting for a command");
    }

    // DWT cycle counter: interrupt timing figures and the link's timeouts.
    // `steal`, not `take`: `take` guards its flag with PRIMASK (cpsid), the
    // only thing in the image that would mask the PWM interrupt.
    // SAFETY: the only use of the core peripherals in the image; DCB/DWT
    // are not touched anywhere else except reading CYCCNT.
    let mut cp = unsafe { cortex_m::Peripherals::steal() };
    cp.DCB.enable_trace();
    cp.DWT.enable_cycle_counter();
    hw::exceptions::enable_fault_exceptions(&mut cp.SCB);
    hw::enable_flash_acceleration();
    if !hw::brake::boot_pin_ignored() {
        error!("option bytes: the BOOT0 pin (PB8, the brake output) selects the boot mode: the bridge stays off; set nSWBOOT0 = 0, nBOOT0 = 1 (docs/firmware-bringup.md, Flashing)");
    }

    let mut board = match board::bring_up(p) {
        Ok(b) => b,
        Err(e) => {
            error!("board bring-up failed: {} (bridge off, brake closed)", e);
            return None;
        }
    };
    let Some(comms) = board.take_comms() else {
        error!("the transports' peripherals were taken already");
        return None;
    };
    let hw::comms::Comms { serial, can: mut can_bus, mut store } = comms.start();
    let Ok(serial) = serial else {
        error!("USART2 configuration refused (baud rate {=u32})", comms::BAUD);
        return None;
    };
    let hw::comms::Serial { tx: uart_tx, rx: mut uart_rx } = serial;
    // Replies and telemetry go out through the transmit queue and this
    // task: the main task never waits for USART2 (`comms`, CAN first).
    match uart_writer(uart_tx) {
        Ok(task) => spawner.spawn(task),
        Err(_) => {
            error!("the USART2 writer task could not start");
            return None;
        }
    }
    info!(
        "USART2 {=u32} Bd (ST-LINK VCP); FDCAN1 {=u32}/{=u32} bit/s, leg slot from control.stream.leg_index",
        comms::BAUD,
        comms::CAN_NOMINAL_BPS,
        comms::CAN_DATA_BPS
    );
    if let Some(irq) = masking::unmasked_interrupt(pac::Interrupt::ADC1_2 as u16) {
        error!("interrupt {=u16} sits at the PWM interrupt's priority: critical sections do not mask it", irq);
    }

    // The watchdog runs from here on, before anything can enable the bridge.
    board::watchdog::start(WATCHDOG_TIMEOUT_MS);
    let mut dog = Watchdog::new();

    // One poll for the interrupt's first snapshot (it publishes from its
    // first period on): if none came, the interrupt is not running, nothing
    // feeds the watchdog, and the reset that follows is the way out.
    Timer::after(STARTUP_POLL).await;
    dog.feed_if_isr_alive();
    if board.snapshot().seq == 0 {
        error!("the PWM interrupt is not running: bridge off; the watchdog will reset");
        return Some(dog);
    }
    let pwm_timer_hz = board.pwm_timer_hz();
    let status = board.status();
    info!(
        "PWM {=f32} Hz centre-aligned, dead time {=u32} ns, HW overcurrent break: {}",
        board::VALID_PARAMS.get().rates.pwm_frequency_hz,
        hw::DEAD_TIME_NS,
        status.hw_overcurrent_armed
    );
    if !status.hw_overcurrent_armed {
        error!("comparator self-test failed (a comparator high with the bridge off): no hardware overcurrent break, the bridge stays off");
    }

    // Current offsets with the bridge off.
    if let Err(e) = board.begin_offset_calibration(OFFSET_CALIBRATION_SAMPLES) {
        error!("the PWM interrupt did not take the calibration request: {} (bridge off)", e);
        return Some(dog);
    }
    let offsets = loop {
        Timer::after(STARTUP_POLL).await;
        dog.feed_if_isr_alive();
        match board.offset_calibration() {
            Calibration::Pending => {}
            Calibration::Done { offset_codes } => break offset_codes,
            Calibration::Failed { offset_codes } => {
                error!("current offsets implausible {} (codes): bridge stays off", offset_codes);
                return Some(dog);
            }
        }
    };
    info!("current offsets (ADC codes) U/V/W = {}", offsets);

    // In a function of its own: the controller (≈ 1.3 KB) and the boot
    // parameters live on its stack frame, not in the main task's state
    // (an async body keeps every local whose scope spans an `await`).
    let hazards = BoardHazards { no_hardware_break: !status.hw_overcurrent_armed, boot_pin_live: !hw::brake::boot_pin_ignored() };
    let (params, boot_record) = install_controller(&mut store, watchdog_reset, hazards);
    let mut can_termination = params.stream.can_termination;
    comms::set_termination(can_termination);

    let mut ticker = Ticker::every(Duration::from_hz(TELEMETRY_HZ));
    let mut tick: u32 = 0;
    let mut button_was = false;
    let mut server = Server::new(IDENTITY, &DEFAULT_PARAMS);
    server.set_boot_record(boot_record);
    let mut reader = FrameReader::new();
    let params_cache = ParamsCache::new(params);
    let mut rx_bytes = [0u8; 64];
    // One transmit buffer for every frame sent (replies, telemetry).
    let mut out = [0u8; proto::FRAME_MAX];
    let mut next_telemetry: Option<Instant> = None;
    let mut can_state = CanStream::default();
    let mut tx_dropped: u32 = 0;
    loop {
        let telemetry_due = async {
            match next_telemetry {
                Some(at) => Timer::at(at).await,
                None => core::future::pending().await,
            }
        };
        // CAN first: when several are ready, the setpoint stream wins (the
        // FDCAN receive FIFO holds 3 frames; the UART ring 5.6 ms of bytes).
        let event = select4(can_bus.read_fd(), uart_rx.read(&mut rx_bytes), ticker.next(), telemetry_due).await;
        match event {
            Either4::Third(()) => {}
            Either4::Second(Ok(n)) => {
                for &byte in rx_bytes.iter().take(n) {
                    // Queued, not awaited: the writer task sends it.
                    let len = {
                        let mut drive = BoardDrive::new(&mut board, &params_cache);
                        match server.receive(&mut reader, byte, &mut drive, &mut store) {
                            Some(reply) => encode_frame(&reply, &mut out),
                            None => 0,
                        }
                    };
                    if !comms::queue_frame(out.get(..len).unwrap_or(&[])) {
                        tx_dropped = report_dropped(tx_dropped);
                    }
                }
                next_telemetry = telemetry_schedule(&server, next_telemetry);
                // A parameter set may have switched the bus terminator.
                if params_cache.can_termination() != can_termination {
                    can_termination = !can_termination;
                    comms::set_termination(can_termination);
                    info!("CAN bus terminator {}", if can_termination { "in" } else { "out" });
                }
                dog.feed_if_isr_alive();
                continue;
            }
            Either4::Second(Err(e)) => {
                // Overrun or a line error: the ring restarts on the next read.
                warn!("USART2 receive: {}", UsartFault::from(e));
                reader = FrameReader::new();
                continue;
            }
            Either4::First(Ok(envelope)) => {
                let frame = envelope.frame;
                if let Some(id) = comms::standard_id(&frame) {
                    let mut drive = BoardDrive::new(&mut board, &params_cache);
                    can_state.receive(id, frame.data(), params_cache.leg_index(), &mut server, &mut drive, &mut store);
                }
                continue;
            }
            Either4::First(Err(e)) => {
                can_state.bus_errors = can_state.bus_errors.wrapping_add(1);
                if can_state.bus_errors.is_power_of_two() {
                    warn!("FDCAN1 bus error {} ({=u32} so far)", CanFault::from(e), can_state.bus_errors);
                }
                continue;
            }
            Either4::Fourth(()) => {
                let now = next_telemetry.unwrap_or_else(Instant::now);
                next_telemetry = telemetry_schedule(&server, Some(now));
                let len = match board.snapshot().drive() {
                    Some((t, _)) => encode_frame(&DriveFrame::Telemetry(server.telemetry_frame(&t)), &mut out),
                    None => 0,
                };
                if !comms::queue_frame(out.get(..len).unwrap_or(&[])) {
                    tx_dropped = report_dropped(tx_dropped);
                }
                continue;
            }
        }
        tick = tick.wrapping_add(1);
        dog.feed_if_isr_alive();

        let snapshot = board.snapshot();
        let Some((telemetry, _moving)) = snapshot.drive() else {
            continue;
        };
        let mode = telemetry.mode;
        info!("tlm {}", telemetry);

        // Button: acknowledge faults, else toggle the bridge.
        let pressed = board.button_pressed();
        if pressed && !button_was {
            on_button(&mut board, mode);
        }
        button_was = pressed;

        board.set_led(led_pattern(mode, tick));

        if tick.is_multiple_of(HEARTBEAT_EVERY) {
            let isr = ISR_STATS.snapshot();
            let status = snapshot.status;
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
            let c = &can_state;
            info!(
                "can: accepted={=u32} refused={=u32} stale={=u32} bad={=u32} other_legs={=u32} bus_errors={=u32}",
                c.accepted, c.refused, c.stale, c.bad, c.other_legs, c.bus_errors
            );
        }
    }
}

/// What the board found at start-up that forbids the bridge.
#[derive(Clone, Copy)]
struct BoardHazards {
    /// The comparator self-test failed: no hardware overcurrent break.
    no_hardware_break: bool,
    /// The option bytes let PB8 (BOOT0, the brake output) pick the boot mode.
    boot_pin_live: bool,
}

/// Builds the controller from the saved set (schema-checked, validated,
/// lowered to the board's ratings) or the image's (validated when it was
/// built), attaches the capture store, applies
/// `control.startup.run_at_power_up` and hands it to the interrupt; the
/// parameters it runs with.
#[inline(never)]
fn install_controller(store: &mut FlashStore, watchdog_reset: bool, hazards: BoardHazards) -> (servo_core::ControlParams, BootRecord) {
    let (boot_params, boot_record) = load_params(store);
    let params = *boot_params.get();
    let mut controller = Controller::from_validated(boot_params);
    // Observer weights uploaded and stored with that record run in place
    // from flash; otherwise the compiled ones.
    if boot_record == BootRecord::Loaded {
        match store.stored_observer() {
            Ok(Some(w)) if controller.command(servo_core::Command::SetObserverWeights { weights: w }).is_ok() => {
                board::drive::note_observer(w);
                info!("observer: uploaded weights from flash");
            }
            Ok(_) => {}
            Err(why) => warn!("observer: compiled weights (stored block: {=str})", why.as_str()),
        }
    }
    // The capture store, before the controller goes to the interrupt.
    controller.attach_capture_store(&link::CAPTURE);
    if watchdog_reset {
        controller.report_watchdog_reset();
    }
    // Standing conditions: the bridge never enables while they stand (the
    // PWM interrupt keeps it off besides).
    controller.report_board_condition(FaultSet::NO_HARDWARE_BREAK, hazards.no_hardware_break);
    controller.report_board_condition(FaultSet::BOOT_OPTION_BYTES, hazards.boot_pin_live);
    let faults = controller.faults();
    if !faults.is_empty() {
        error!("controller refuses to run: faults {}", faults);
    }
    // The one switch for moving unasked after power-up or any reset:
    // `control.startup.run_at_power_up` (default false). A latched fault
    // (a watchdog reset among them) refuses it: the drive then waits.
    if params.startup.run_at_power_up {
        match controller.power_up() {
            Ok(_) => warn!("startup.run_at_power_up: the drive starts by itself"),
            Err(e) => warn!("startup.run_at_power_up refused: {}", e),
        }
    } else {
        info!("ready: waiting for a command (bridge off, brake closed)");
    }
    if link::install_controller(controller).is_err() {
        error!("a controller was installed already");
    }
    (params, boot_record)
}

/// The parameters to start with: the record saved in flash if it is whole,
/// of this schema and valid (lowered to the board's ratings, like the
/// image's), else the image's own; the log says which and why.
/// With what became of the saved record, for `Info` and `Status`.
fn load_params(store: &mut FlashStore) -> (ValidatedParams, BootRecord) {
    let rejected = |why: RecordRejection, leaf: u16| BootRecord::Rejected { why, leaf };
    let mut buf = [0u8; record::RECORD_MAX];
    let n = match store.load(&mut buf) {
        Ok(0) => {
            info!("parameters: image defaults (no record in flash)");
            return (board::VALID_PARAMS, BootRecord::NoRecord);
        }
        Ok(n) => n,
        Err(why) => {
            warn!("parameters: image defaults (flash: {=str})", why.as_str());
            return (board::VALID_PARAMS, rejected(RecordRejection::Storage, u16::MAX));
        }
    };
    let saved = match record::decode(buf.get(..n).unwrap_or(&[])) {
        Ok(p) => p,
        Err(e) => {
            warn!("parameters: image defaults (flash record refused: {=str})", e.reason());
            return (board::VALID_PARAMS, BootRecord::of_error(&e));
        }
    };
    let (lowered, applied) = hw::apply_board_limits(*saved.get());
    if applied != hw::BoardLimitsApplied::default() {
        warn!("saved parameters lowered to the board's ratings: {}", applied);
    }
    match ValidatedParams::new(lowered) {
        Ok(v) if !hw::can_drive_termination(v.get()) => {
            warn!(
                "parameters: image defaults (saved set asks for leaf {=u16}, control.stream.can_termination, which this board cannot switch)",
                servo_core::leaf!(stream.can_termination)
            );
            (board::VALID_PARAMS, rejected(RecordRejection::Invalid, servo_core::leaf!(stream.can_termination)))
        }
        Ok(v) => {
            info!("parameters: loaded from flash ({=usize} bytes, schema checked)", n);
            (v, BootRecord::Loaded)
        }
        Err(e) => {
            // The leaf by index: the image holds no parameter names
            // (`drive param list` shows index and path).
            warn!("parameters: image defaults (saved set invalid on this board: leaf {=u16}: {})", e.leaf, e.reason);
            (board::VALID_PARAMS, rejected(RecordRejection::Invalid, e.leaf))
        }
    }
}

/// When the next telemetry frame is due at the server's configured rate
/// (from `from`, or now), `None` when telemetry is off.
fn telemetry_schedule(server: &Server<&'static ValidatedParams>, from: Option<Instant>) -> Option<Instant> {
    let hz = server.telemetry_rate_hz();
    if hz == 0 {
        return None;
    }
    let period = Duration::from_hz(u64::from(hz));
    let now = Instant::now();
    match from {
        // Keep the cadence; after a stall, restart from now.
        Some(at) if at + period > now => Some(at + period),
        _ => Some(now + period),
    }
}

/// Encodes `frame` (COBS, CRC, delimiter) into `buf`; its length (0 if it
/// does not fit, which the protocol tests rule out).
#[inline(never)]
fn encode_frame(frame: &DriveFrame, buf: &mut [u8; proto::FRAME_MAX]) -> usize {
    proto::encode(frame, buf).map_or(0, |bytes| bytes.len())
}

/// Sends what the main task queued, by DMA, for ever. The only code that
/// awaits USART2's transmitter.
#[embassy_executor::task]
async fn uart_writer(mut tx: embassy_stm32::usart::UartTx<'static, embassy_stm32::mode::Async>) {
    let mut chunk = [0u8; 64];
    loop {
        let n = comms::TX_QUEUE.read(&mut chunk).await;
        if tx.write(chunk.get(..n).unwrap_or(&[])).await.is_err() {
            warn!("USART2 transmit failed");
        }
    }
}

/// Counts a frame the transmit queue had no room for, and says so (at
/// powers of two, so a stalled host does not flood the log).
fn report_dropped(dropped: u32) -> u32 {
    let n = dropped.wrapping_add(1);
    if n.is_power_of_two() {
        warn!("USART2 transmit queue full: frame dropped ({=u32} so far)", n);
    }
    n
}

/// LED: on = running, 1 Hz blink = disabled (waiting for a command), 5 Hz =
/// fault, 2 Hz = any other mode (the drive is busy on its own: aligning,
/// stopping, braking, or a lifecycle step added later).
fn led_pattern(mode: Mode, tick: u32) -> bool {
    let blink = |hz: u32| (tick / (TELEMETRY_HZ as u32 / (2 * hz)).max(1)).is_multiple_of(2);
    match mode {
        Mode::Running => true,
        Mode::Disabled => blink(1),
        Mode::Fault => blink(5),
        _ => blink(2),
    }
}

/// Feeds the watchdog only while the PWM interrupt keeps running: a hung
/// interrupt, a dead ADC trigger or a hung executor all end in a reset, which
/// comes back with the bridge off, the brake closed and the drive waiting.
struct Watchdog {
    isr_periods_at_feed: u32,
}

impl Watchdog {
    fn new() -> Self {
        Self { isr_periods_at_feed: ISR_STATS.snapshot().periods }
    }

    fn feed_if_isr_alive(&mut self) {
        let periods = ISR_STATS.snapshot().periods;
        if periods != self.isr_periods_at_feed {
            board::watchdog::feed();
            self.isr_periods_at_feed = periods;
        }
    }
}

/// Sends a command to the drive and logs the outcome. True if accepted.
fn send(board: &mut hw::Board, cmd: Command) -> bool {
    match board.call(Request::Drive(cmd)) {
        Ok(Reply::Drive(Ok(outcome))) => {
            info!("{} -> {}", cmd, outcome);
            true
        }
        Ok(Reply::Drive(Err(e))) => {
            warn!("{} refused: {}", cmd, e);
            false
        }
        Ok(other) => {
            warn!("{} not taken: {}", cmd, other);
            false
        }
        Err(e) => {
            error!("{} lost: {} (is the PWM interrupt running?)", cmd, e);
            false
        }
    }
}

/// Button: first acknowledges whatever is latched (board trip, controller
/// faults); with nothing latched it toggles the bridge between Disabled and
/// Running. In any other mode the drive is busy on its own: ignored.
fn on_button(board: &mut hw::Board, mode: Mode) {
    if board.status().hw_overcurrent_tripped {
        if board.clear_latched_faults() {
            info!("hardware overcurrent trip cleared");
        } else {
            warn!("hardware overcurrent still present: cannot clear");
        }
        return;
    }
    match mode {
        Mode::Fault => {
            send(board, Command::ClearFaults);
        }
        Mode::Running => {
            send(board, Command::Disable);
        }
        // `StartUp` runs whatever start-up step is still missing (offsets,
        // commutation, homing) and ends holding; a drive that is ready
        // already simply enables (preload, then the brake lets go).
        Mode::Disabled => {
            send(board, Command::StartUp);
        }
        _ => info!("button ignored in {}", mode),
    }
}

/// Stays here for ever, bridge off, brake closed, still logging why; keeps
/// the watchdog fed (if it runs) while the PWM interrupt lives, so the log
/// stays readable instead of a reset loop.
async fn park(mut dog: Option<Watchdog>) -> ! {
    let mut ticks: u32 = 0;
    loop {
        Timer::after(STARTUP_POLL).await;
        if let Some(d) = dog.as_mut() {
            d.feed_if_isr_alive();
        }
        ticks = ticks.wrapping_add(1);
        if ticks.is_multiple_of(500) {
            error!("parked: see the first error above");
        }
    }
}
