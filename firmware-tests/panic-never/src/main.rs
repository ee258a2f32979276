//! No panic on the control path, proven at link time (the "panic-never"
//! technique).
//!
//! The panic handler below calls `__panic_reachable_on_the_control_path`,
//! which exists nowhere. The optimiser (release profile, fat LTO) deletes
//! every panic it can prove unreachable; if any panic is still reachable
//! from the calls in `main`, the handler stays in the image and the link
//! fails naming that symbol. `bash firmware-tests/panic-never/check.sh`
//! builds it and, on failure, lists the functions that still call into
//! the panic machinery.
//!
//! Everything the interrupt and the main task call on a `Controller` is
//! called here, with inputs read through `read_volatile` so the compiler
//! knows nothing about them — not even the parameters: the proof is for any
//! `ControlParams` and any `SensorSample`, NaN and infinities included.
#![no_std]
#![no_main]

use core::panic::PanicInfo;
use core::ptr::{addr_of, addr_of_mut, read_volatile, write_volatile};

use cortex_m_rt::entry;
use servo_core::{Command, ControlParams, Controller, PwmCommand, SensorSample};

extern "C" {
    /// Deliberately undefined: referenced only if a panic is reachable.
    fn __panic_reachable_on_the_control_path() -> !;
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    // SAFETY: never runs; the link fails if this call survives optimisation.
    unsafe { __panic_reachable_on_the_control_path() }
}

// Opaque inputs and a sink for outputs.
static mut PARAMS: ControlParams = ControlParams::DEFAULT;
static mut SAMPLE: SensorSample = SensorSample::idle(48.0);
static mut SELECT: u32 = 0;
static mut ARG: f32 = 0.0;
static mut SINK: [u32; 8] = [0; 8];

fn opaque<T: Copy>(p: *const T) -> T {
    // SAFETY: single-threaded, the statics are always initialised.
    unsafe { read_volatile(p) }
}

fn sink(slot: usize, v: u32) {
    // SAFETY: as above; `slot & 7` keeps the index in range.
    unsafe { write_volatile(addr_of_mut!(SINK[slot & 7]), v) }
}

fn out(c: &PwmCommand) {
    sink(0, c.duty[0].to_bits());
    sink(1, c.duty[1].to_bits());
    sink(2, c.duty[2].to_bits());
    sink(3, c.enable as u32);
}

fn command(c: &mut Controller) {
    let arg = opaque(addr_of!(ARG));
    let cmd = match opaque(addr_of!(SELECT)) % 8 {
        0 => Command::Enable,
        1 => Command::Disable,
        2 => Command::MoveTo { position_m: arg },
        3 => Command::SetHome { position_m: arg },
        4 => Command::Align,
        5 => Command::ClearFaults,
        6 => Command::SetCompensation { enabled: arg > 0.0 },
        _ => Command::SetPositionShift { shift_m: arg },
    };
    sink(4, c.command(cmd).is_ok() as u32);
}

/// The lock-free hand-over the firmware's interrupt and main task use
/// (`servo_core::mailbox`): every operation, on opaque payloads.
fn mailbox() {
    use servo_core::mailbox::{Handoff, Slot, TripleBuffer};
    static SLOT: Slot<SensorSample> = Slot::new();
    static TRIPLE: TripleBuffer<SensorSample> = TripleBuffer::new(SensorSample::idle(0.0));
    static HANDOFF: Handoff<SensorSample> = Handoff::new();
    let s = opaque(addr_of!(SAMPLE));
    if let Some((mut tx, mut rx)) = SLOT.split() {
        sink(0, tx.try_put(s).is_ok() as u32 ^ tx.is_empty() as u32);
        if opaque(addr_of!(SELECT)) == 7 {
            sink(0, tx.try_withdraw().map_or(0, |v| v.encoder_count as u32));
        }
        sink(1, rx.try_take().map_or(0, |v| v.encoder_count as u32));
    }
    if let Some((mut w, mut r)) = TRIPLE.split() {
        w.publish(s);
        sink(2, r.has_fresh() as u32 ^ r.read().bus_voltage_v.to_bits());
    }
    sink(3, HANDOFF.put(s).is_ok() as u32 ^ HANDOFF.is_filled() as u32);
    if let Some(v) = HANDOFF.claim() {
        v.encoder_count = v.encoder_count.wrapping_add(1);
        sink(4, v.encoder_count as u32);
    }
}

/// The protocol on opaque bytes: `Server::receive` (frame reader, decoding,
/// every request handled against the controller), replies and telemetry
/// encoded; `apply_params` and the parameter record on opaque parameters.
mod protocol {
    use super::*;
    use servo_core::controller::ApplyError;
    use servo_core::params::{record, ValidatedParams};
    use servo_core::protocol::*;
    use servo_core::{CommandError, CommandOutcome};

    pub struct Drive<'a>(pub &'a mut Controller);

    impl DriveAccess for Drive<'_> {
        fn status(&self) -> DriveStatus {
            DriveStatus { telemetry: self.0.telemetry(), test_running: false }
        }
        fn params(&self) -> ControlParams {
            *self.0.params()
        }
        fn command(&mut self, cmd: Command) -> Result<CommandOutcome, CommandError> {
            self.0.command(cmd)
        }
        fn apply_params(&mut self, p: &ValidatedParams) -> Result<(), ApplyError> {
            self.0.apply_params(p)
        }
        fn capture(&mut self, _: &CaptureRequest) -> Result<CaptureReply, Reason> {
            Err(Reason::NoCaptureStore)
        }
        fn test_signal(&mut self, _: &TestSignal) -> Result<(), Reason> {
            Err(Reason::NotRunning)
        }
        fn observer_weights(&self) -> &'static servo_core::observer::block::Weights {
            self.0.observer_weights()
        }
    }

    static mut STAGING: servo_core::observer::block::Staging = servo_core::observer::block::Staging::new();

    pub struct Store;

    impl ParamStore for Store {
        fn save(&mut self, record: &[u8]) -> Result<(), Text> {
            sink(6, record.len() as u32);
            Ok(())
        }
        fn load(&mut self, buf: &mut [u8]) -> Result<usize, Text> {
            let n = opaque(addr_of!(SELECT)) as usize;
            for (i, b) in buf.iter_mut().enumerate() {
                *b = opaque(addr_of!(SELECT)).wrapping_add(i as u32) as u8;
            }
            Ok(n)
        }
        fn observer_staging(&mut self) -> Option<&mut servo_core::observer::block::Staging> {
            // SAFETY: one thread; the only reference to it at a time.
            Some(unsafe { &mut *core::ptr::addr_of_mut!(STAGING) })
        }
    }

    static mut BYTES: [u8; 64] = [0; 64];

    pub fn serve(c: &mut Controller, srv: &mut Server, reader: &mut FrameReader) {
        let mut out = [0u8; FRAME_MAX];
        for i in 0..64 {
            // SAFETY: as `opaque`; `i < 64`.
            let b = unsafe { read_volatile(addr_of!(BYTES[i])) };
            // The parser and the whole server: any bytes, any frame, any
            // request (parameters by index through the leaf table, record,
            // stream, capture, test). Linked because the drive does not
            // use miniconf's derived `TreeAny` (its child match ends in
            // `unreachable!()`); the 10⁶-frame property test covers the
            // behaviour, host-sim/tests/protocol_fuzz.rs.
            let reply = srv.receive(reader, b, &mut Drive(c), &mut Store);
            if let Some(reply) = reply {
                sink(7, encode(&reply, &mut out).map_or(0, |f| f.len() as u32));
            }
        }
        let t = srv.telemetry_frame(&c.telemetry());
        sink(7, encode(&DriveFrame::Telemetry(t), &mut out).map_or(0, |f| f.len() as u32));
        if let Ok(v) = ValidatedParams::new(opaque(addr_of!(PARAMS))) {
            sink(6, c.apply_params(&v).is_ok() as u32);
        }
        let mut rec = [0u8; record::RECORD_MAX];
        sink(6, record::encode(&opaque(addr_of!(PARAMS)), Some(c.observer_weights()), &mut rec).map_or(0, |r| r.len() as u32));
        sink(6, record::decode_record(&rec).is_ok() as u32);
    }
}

/// The scope and the test signals (the protocol server's calls, on the
/// board through the interrupt's request slot).
fn scope(c: &mut Controller) {
    use servo_core::capture::CaptureStore;
    use servo_core::protocol::{CaptureConfig, CaptureTrigger, ChirpTarget, Signal, TestSignal};
    static STORE: CaptureStore = CaptureStore::new();
    let sel = opaque(addr_of!(SELECT));
    let arg = opaque(addr_of!(ARG));
    if sel == 3 {
        c.attach_capture_store(&STORE);
    }
    let mut signals = servo_core::capture::SignalList::EMPTY;
    let all = [Signal::CurrentQ, Signal::Speed, Signal::MotorPosition, Signal::ElectricalAngle, Signal::PhaseCurrentC];
    for k in 0..(sel & 7) as usize {
        let _ = signals.push(all.get(k % all.len()).copied().unwrap_or(Signal::BusVoltage));
    }
    let cfg = CaptureConfig {
        signals,
        decimation: (sel >> 8) as u16,
        samples: (sel >> 12) as u16,
        pre_trigger: (sel >> 16) as u16,
        trigger: if sel & 8 != 0 { CaptureTrigger::Fault } else { CaptureTrigger::TestStart },
    };
    sink(0, c.capture_configure(&cfg).is_ok() as u32);
    sink(1, c.capture_trigger().is_ok() as u32 ^ c.capture_status().trigger_index as u32);
    let mut buf = [0.0f32; 64];
    sink(2, c.capture_read((sel >> 20) as u8, (sel >> 4) as u16, &mut buf[..(sel as usize >> 24) & 63]).unwrap_or(0) as u32);
    sink(3, buf[5].to_bits());
    let t = match sel % 5 {
        0 => TestSignal::CurrentStep { axis_q: sel & 16 != 0, amplitude_a: arg, duration_s: arg },
        1 => TestSignal::SpeedStep { amplitude_rad_s: arg, duration_s: arg },
        2 => TestSignal::PositionStep { distance_m: arg, duration_s: arg },
        3 => TestSignal::Chirp { target: ChirpTarget::Current, amplitude: arg, start_hz: arg, end_hz: arg * 2.0, duration_s: arg },
        _ => TestSignal::Chirp { target: ChirpTarget::Position, amplitude: arg, start_hz: arg, end_hz: arg * 2.0, duration_s: arg },
    };
    sink(4, c.start_test(t).is_ok() as u32 ^ c.test_running() as u32);
    if sel == 77 {
        c.stop_test();
    }
}

#[entry]
fn main() -> ! {
    let params = opaque(addr_of!(PARAMS));
    let mut c = match opaque(addr_of!(SELECT)) {
        0 => Controller::new(params),
        _ => match Controller::try_new(params) {
            Ok(c) => c,
            Err(e) => {
                sink(5, u32::from(e.leaf));
                Controller::new(ControlParams::DEFAULT)
            }
        },
    };
    let mut srv = servo_core::protocol::Server::new(
        servo_core::protocol::Identity { firmware_version: "0", git_hash: "0", board: "0" },
        match servo_core::params::ValidatedParams::new(ControlParams::DEFAULT) {
            Ok(v) => v,
            Err(_) => loop {},
        },
    );
    let mut reader = servo_core::protocol::FrameReader::new();
    loop {
        // The protocol, between two steps.
        protocol::serve(&mut c, &mut srv, &mut reader);
        // The interrupt's calls.
        let s = opaque(addr_of!(SAMPLE));
        out(&c.step(&s));
        if opaque(addr_of!(SELECT)) == 99 {
            c.report_isr_overrun();
        }
        // The main task's calls.
        command(&mut c);
        scope(&mut c);
        mailbox();
        let t = c.telemetry();
        sink(
            5,
            t.position_command_m.to_bits() ^ t.faults.bits() as u32 ^ t.limits.bits() as u32,
        );
        sink(
            6,
            c.mode() as u32 ^ c.faults().bits() as u32 ^ c.move_in_progress() as u32,
        );
        sink(
            7,
            c.motor_position_m().to_bits() ^ c.speed_rad_s().to_bits(),
        );
    }
}
