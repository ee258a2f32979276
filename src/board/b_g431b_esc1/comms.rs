//! The ESC1's transports and parameter flash: USART2 to the ST-LINK's
//! virtual COM port, FDCAN1 to the on-board CAN transceiver, and the
//! parameter record in the last two flash pages.
//!
//! | what | pins / resource | set-up |
//! |---|---|---|
//! | USART2 → ST-LINK/V2-1 VCP | PB3 TX, PB4 RX (AF7) | [`BAUD`] 8N1, DMA1 CH1 TX, DMA1 CH2 RX into a [`RX_RING_LEN`]-byte ring (no interrupt per byte) |
//! | FDCAN1 → CAN transceiver | PA11 RX, PB9 TX (AF9) | CAN FD + BRS, 1 Mbit/s nominal, 5 Mbit/s data, kernel clock PCLK1 = 170 MHz |
//! | transceiver shutdown (CAN_SHDN) | PC11, push-pull output | driven low: transceiver on (high = shut down); driven before FDCAN1 starts |
//! | bus termination (CAN_TERM) | PC14, push-pull output | high: the board's 120 Ω across CANH–CANL; low: none ([`set_termination`]) |
//! | parameter record | flash pages 62–63 (0x0801_F000…0x0801_FFFF) | two-page A/B record store ([`FlashStore`]) |
//!
//! Replies and telemetry are never awaited by the main task: it puts each
//! encoded frame into [`TX_QUEUE`] (whole or not at all) and a writer task
//! of its own (`uart_writer` in main.rs) sends the queue by DMA. So a 320-byte reply (3.5 ms
//! on the line) never holds up CAN reception: the FDCAN receive FIFO holds
//! 3 frames, and the platform's setpoint frames come every millisecond.
//!
//! Interrupts (`USART2`, `DMA1_CHANNEL1/2`, `FDCAN1_IT0/IT1`) sit at
//! [`super::COMMS_IRQ_PRIORITY`] / [`super::DMA_IRQ_PRIORITY`], below the PWM
//! interrupt and inside what a thread-mode critical section masks
//! (`set_interrupt_priorities`, checked by `masking::unmasked_interrupt`).

use core::num::{NonZeroU16, NonZeroU8};
use core::sync::atomic::Ordering;

use embassy_stm32::can::config::{DataBitTiming, FrameTransmissionConfig, GlobalFilter, NominalBitTiming};
use embassy_stm32::can::filter::{Action, FilterType, StandardFilter, StandardFilterSlot};
use embassy_stm32::can::frame::FdFrame;
use embedded_can::{Id, StandardId};
use embassy_stm32::can::{Can, CanConfigurator, OperatingMode};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::{DMA1_CH1, DMA1_CH2, FDCAN1, FLASH, PA11, PB3, PB4, PB9, PC11, PC14, USART2};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::pipe::Pipe;
use embassy_stm32::usart::{self, RingBufferedUartRx, Uart, UartTx};
use embassy_stm32::{bind_interrupts, can, dma, pac, Peri};
use servo_core::observer::block::{Staging, Weights};
use servo_core::params::record::{self, RECORD_MAX};
use servo_core::protocol::can::{SETPOINT_ID, STOP_ID};
use servo_core::protocol::server::text;
use servo_core::protocol::{ParamStore, Text};

use super::super::FLASH_STALL;

pub use super::comms_sizes::BAUD;
/// Receive ring (DMA, circular), in [`super::comms_sizes`] with the other
/// sizes the comms test models. 512 B = 5.6 ms of bytes at full line rate
/// (92 bytes/ms). The main task drains it between CAN frames and never
/// waits for a transmission (replies go through [`TX_QUEUE`]); the host
/// sends one request and waits for its reply (the protocol is
/// request–reply; the setpoint stream at rate comes over CAN), so what can
/// arrive meanwhile is at most one request frame (≤ 320 bytes). A flash
/// erase (≤ 40 ms stall of the CPU, not of the DMA) happens only during
/// `Save`, when the host waits for the reply. An overrun is reported by
/// the ring and the frame reader restarts (the host's request times out
/// and is repeated).
pub use super::comms_sizes::{RX_RING_LEN, TX_QUEUE_LEN};
/// CAN FD nominal (arbitration) bit rate.
pub const CAN_NOMINAL_BPS: u32 = 1_000_000;
/// CAN FD data-phase bit rate (bit-rate switching).
pub const CAN_DATA_BPS: u32 = 5_000_000;
/// FDCAN kernel clock: PCLK1 (`clock_config` selects it).
const CAN_KERNEL_HZ: u32 = 170_000_000;

bind_interrupts!(pub struct Irqs {
    USART2 => usart::InterruptHandler<USART2>;
    DMA1_CHANNEL1 => dma::InterruptHandler<DMA1_CH1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<DMA1_CH2>;
    FDCAN1_IT0 => can::IT0InterruptHandler<FDCAN1>;
    FDCAN1_IT1 => can::IT1InterruptHandler<FDCAN1>;
});

/// The peripherals the transports and the store use, set aside by
/// `Board::new` (which takes all of embassy's `Peripherals`).
pub struct CommsPeripherals {
    pub(super) usart2: Peri<'static, USART2>,
    pub(super) usart_tx: Peri<'static, PB3>,
    pub(super) usart_rx: Peri<'static, PB4>,
    pub(super) dma_tx: Peri<'static, DMA1_CH1>,
    pub(super) dma_rx: Peri<'static, DMA1_CH2>,
    pub(super) fdcan1: Peri<'static, FDCAN1>,
    pub(super) can_rx: Peri<'static, PA11>,
    pub(super) can_tx: Peri<'static, PB9>,
    pub(super) can_shdn: Peri<'static, PC11>,
    pub(super) can_term: Peri<'static, PC14>,
    pub(super) flash: Peri<'static, FLASH>,
}

/// The serial link's two halves.
pub struct Serial {
    pub tx: UartTx<'static, Async>,
    pub rx: RingBufferedUartRx<'static>,
}

/// What the transports' bring-up returns.
pub struct Comms {
    pub serial: Result<Serial, usart::ConfigError>,
    pub can: Can<'static>,
    pub store: FlashStore,
}

impl CommsPeripherals {
    /// Starts USART2 (ring-buffered DMA reception running) and FDCAN1
    /// (normal mode, filters: the setpoint and stop identifiers into FIFO 0),
    /// and opens the parameter store.
    /// The transceiver is switched on and its terminator left out until
    /// the parameters are known ([`set_termination`]).
    pub fn start(self) -> Comms {
        transceiver_pins();
        // Held for ever by being consumed here: nobody else gets the pins.
        let _ = (self.can_shdn, self.can_term);
        Comms {
            serial: serial(self.usart2, self.usart_rx, self.usart_tx, self.dma_tx, self.dma_rx),
            can: fdcan(self.fdcan1, self.can_rx, self.can_tx),
            store: FlashStore { _flash: self.flash, staging: Staging::new() },
        }
    }
}

fn serial(
    usart2: Peri<'static, USART2>,
    rx: Peri<'static, PB4>,
    tx: Peri<'static, PB3>,
    dma_tx: Peri<'static, DMA1_CH1>,
    dma_rx: Peri<'static, DMA1_CH2>,
) -> Result<Serial, usart::ConfigError> {
    static mut RX_RING: [u8; RX_RING_LEN] = [0; RX_RING_LEN];
    let mut config = usart::Config::default();
    config.baudrate = BAUD;
    let (tx, rx) = Uart::new(usart2, rx, tx, dma_tx, dma_rx, Irqs, config)?.split();
    // SAFETY: `CommsPeripherals` exists once (`Board::take_comms` hands it
    // out once), so this runs once and the ring has one owner for ever.
    let ring = unsafe { &mut *core::ptr::addr_of_mut!(RX_RING) };
    let mut rx = rx.into_ring_buffered(ring);
    rx.start_uart();
    Ok(Serial { tx, rx })
}

/// The frames on their way out of USART2, in order (see the module's
/// introduction). A critical section guards it: BASEPRI, never the PWM
/// interrupt (`masking`).
pub static TX_QUEUE: Pipe<CriticalSectionRawMutex, TX_QUEUE_LEN> = Pipe::new();

/// Queues one encoded frame for USART2, whole or not at all, without
/// waiting. False if the queue has no room for it (the frame is dropped:
/// the caller counts and reports it).
pub fn queue_frame(bytes: &[u8]) -> bool {
    super::comms_sizes::queue_whole(&TX_QUEUE, bytes)
}

/// Drives the CAN transceiver's two control pins low: shutdown off (the
/// transceiver on), terminator out. Output speed low; no pull (driven).
fn transceiver_pins() {
    let port = pac::GPIOC;
    for pin in [CAN_SHDN_PIN, CAN_TERM_PIN] {
        port.bsrr().write(|w| w.set_br(pin, true));
        port.otyper().modify(|w| w.set_ot(pin, pac::gpio::vals::Ot::PUSH_PULL));
        port.ospeedr().modify(|w| w.set_ospeedr(pin, pac::gpio::vals::Ospeedr::LOW_SPEED));
        port.pupdr().modify(|w| w.set_pupdr(pin, pac::gpio::vals::Pupdr::FLOATING));
        port.moder().modify(|w| w.set_moder(pin, pac::gpio::vals::Moder::OUTPUT));
    }
}

/// Switches the board's bus terminator in or out (a parameter change takes
/// effect at once).
pub fn set_termination(on: bool) {
    pac::GPIOC.bsrr().write(|w| if on { w.set_bs(CAN_TERM_PIN, true) } else { w.set_br(CAN_TERM_PIN, true) });
}

/// PC11 and PC14 (port C).
const CAN_SHDN_PIN: usize = 11;
const CAN_TERM_PIN: usize = 14;

/// A received frame's standard identifier (`None` for an extended one).
pub fn standard_id(frame: &FdFrame) -> Option<u16> {
    match frame.id() {
        Id::Standard(id) => Some(id.as_raw()),
        Id::Extended(_) => None,
    }
}

fn nz8(v: u8) -> NonZeroU8 {
    NonZeroU8::new(v).unwrap_or(NonZeroU8::MIN)
}

fn fdcan(fdcan1: Peri<'static, FDCAN1>, rx: Peri<'static, PA11>, tx: Peri<'static, PB9>) -> Can<'static> {
    let mut can = CanConfigurator::new(fdcan1, rx, tx, Irqs);
    // 170 MHz kernel clock, prescaler 1 in both phases.
    // Nominal: 170 tq per bit = 1 + 135 + 34, sample point 80 %.
    // Data: 34 tq per bit = 1 + 26 + 7, sample point 79 %.
    const _: () = assert!(CAN_KERNEL_HZ / CAN_NOMINAL_BPS == 170 && CAN_KERNEL_HZ / CAN_DATA_BPS == 34);
    let one = NonZeroU16::MIN;
    let config = can
        .config()
        .set_nominal_bit_timing(NominalBitTiming { prescaler: one, seg1: nz8(135), seg2: nz8(34), sync_jump_width: nz8(34) })
        .set_data_bit_timing(DataBitTiming {
            transceiver_delay_compensation: true,
            prescaler: one,
            seg1: nz8(26),
            seg2: nz8(7),
            sync_jump_width: nz8(7),
        })
        .set_frame_transmit(FrameTransmissionConfig::AllowFdCanAndBRS)
        // Only the layout's two identifiers reach the FIFO.
        .set_global_filter(GlobalFilter::reject_all());
    can.set_config(config);
    let id = |raw: u16| StandardId::new(raw).unwrap_or(StandardId::ZERO);
    can.properties().set_standard_filter(
        StandardFilterSlot::_0,
        StandardFilter { filter: FilterType::DedicatedDual(id(STOP_ID), id(SETPOINT_ID)), action: Action::StoreInFifo0 },
    );
    let can = can.start(OperatingMode::NormalOperationMode);
    enable_transceiver_delay_compensation();
    can
}

/// At 5 Mbit/s a bit (200 ns) is shorter than the transceiver's loop delay,
/// so the transmitter checks its data-phase bits at a compensated point
/// (DBTP.TDC, TDCR.TDCO = the data sample point, 27 tq). embassy-stm32 0.6
/// does not program it on the G4: set here, back in configuration mode.
fn enable_transceiver_delay_compensation() {
    let r = pac::FDCAN1;
    r.cccr().modify(|w| w.set_init(true));
    let mut spins = 0u32;
    while !r.cccr().read().init() && spins < 100_000 {
        spins += 1;
    }
    r.cccr().modify(|w| w.set_cce(true));
    r.tdcr().write(|w| {
        w.set_tdco(27);
        w.set_tdcf(0);
    });
    r.dbtp().modify(|w| w.set_tdc(true));
    r.cccr().modify(|w| {
        w.set_cce(false);
        w.set_init(false);
    });
}

// ---------------------------------------------------------------------------
// Parameter record store.

/// First byte of the store, from the start of flash: the last two 2 KiB
/// pages (memory.x stops the image below it).
pub const STORE_OFFSET: u32 = 0x1_F000;
/// The G431's page (erase unit).
pub const PAGE_BYTES: u32 = 2048;
/// Page header: magic, sequence, record length, complement of the length.
const HEADER_BYTES: usize = 16;
const STORE_MAGIC: [u8; 4] = *b"CSPS";
/// Flash programs double words.
const WRITE_UNIT: usize = 8;
const _: () = assert!(HEADER_BYTES + RECORD_MAX <= PAGE_BYTES as usize);

/// The parameter record in flash, two pages used in turn: a save erases
/// the page *not* holding the newest record and writes there (record
/// first, header last), so a reset or power loss in the middle leaves the
/// previous record whole. The newest page whose record decodes wins; each
/// page is erased every other save (10 000 cycles → 20 000 saves).
///
/// Written directly on the flash registers rather than with
/// sequential-storage over embassy's flash driver: one ≤ 1 KiB record saved
/// by hand needs no map or wear levelling, and embassy-stm32 0.6's G4 page
/// erase sets the erase going inside `cortex_m::interrupt::free` (PRIMASK),
/// which would mask the PWM interrupt from thread mode (the masking check
/// refuses any `cpsid` outside the panic handler). Nothing here masks.
///
/// Flash erase and programming stall instruction fetch (one bank): the PWM
/// interrupt, in flash, misses periods for up to one page erase (≈ 22 ms,
/// 40 ms max). `save` therefore refuses while the bridge is on (MOE set;
/// the server refuses `Save` outside Disabled/Fault already), raises
/// `FLASH_STALL` so the interrupt does not report the missed periods as an
/// overrun, and feeds the watchdog before and after.
///
/// An uploaded observer block is gathered in `staging` (its only RAM copy)
/// and, once stored, run in place from the newest page
/// ([`ParamStore::stored_observer`]): the server points the controller at
/// the new page after every save, before the next save can erase the old.
pub struct FlashStore {
    /// Held so embassy never hands the flash to anyone else.
    _flash: Peri<'static, FLASH>,
    staging: Staging,
}

#[derive(Clone, Copy)]
struct PageHeader {
    seq: u32,
    len: usize,
}

/// Why a flash operation failed (SR error flags).
struct FlashError;

const FLASH_BASE: u32 = 0x0800_0000;
const FLASH_KEY1: u32 = 0x4567_0123;
const FLASH_KEY2: u32 = 0xCDEF_89AB;
/// Page erase ≤ 40 ms, double-word program ≤ 0.1 ms: a bound on the
/// busy-wait far beyond both (≈ 0.2 s at 10 cycles per poll).
const BUSY_POLLS: u32 = 3_000_000;

fn wait_ready() -> Result<(), FlashError> {
    let f = pac::FLASH;
    for _ in 0..BUSY_POLLS {
        let sr = f.sr().read();
        if !sr.bsy() {
            let failed = sr.progerr() || sr.wrperr() || sr.pgaerr() || sr.sizerr() || sr.pgserr() || sr.operr();
            return if failed { Err(FlashError) } else { Ok(()) };
        }
    }
    Err(FlashError)
}

/// Runs `op` with the flash unlocked, errors cleared and the data cache
/// off, then locks it and resets the cache (it may hold the old bytes).
fn with_unlocked(op: impl FnOnce() -> Result<(), FlashError>) -> Result<(), FlashError> {
    let f = pac::FLASH;
    wait_ready()?;
    if f.cr().read().lock() {
        f.keyr().write_value(FLASH_KEY1);
        f.keyr().write_value(FLASH_KEY2);
    }
    // Write-1-to-clear: writing back what is set clears it.
    f.sr().modify(|_| {});
    let dcen = f.acr().read().dcen();
    f.acr().modify(|w| w.set_dcen(false));
    let result = op();
    f.cr().modify(|w| {
        w.set_pg(false);
        w.set_per(false);
        w.set_lock(true);
    });
    f.acr().modify(|w| w.set_dcrst(true));
    f.acr().modify(|w| {
        w.set_dcrst(false);
        w.set_dcen(dcen);
    });
    result
}

fn erase_page(offset: u32) -> Result<(), FlashError> {
    let f = pac::FLASH;
    f.cr().modify(|w| {
        w.set_per(true);
        w.set_pnb((offset / PAGE_BYTES) as u8);
    });
    f.cr().modify(|w| w.set_strt(true));
    let r = wait_ready();
    f.cr().modify(|w| w.set_per(false));
    r
}

/// Programs `bytes` (padded with 0xFF to double words) at `offset`, which
/// is double-word aligned.
fn program(offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
    let f = pac::FLASH;
    f.cr().modify(|w| w.set_pg(true));
    for (i, chunk) in bytes.chunks(WRITE_UNIT).enumerate() {
        let mut dw = [0xFFu8; WRITE_UNIT];
        dw[..chunk.len()].copy_from_slice(chunk);
        let addr = FLASH_BASE + offset + (i * WRITE_UNIT) as u32;
        // SAFETY: an erased, unlocked flash double word inside the store
        // (memory.x keeps the image out of it); PG is set, so the two word
        // writes program it.
        unsafe {
            core::ptr::write_volatile(addr as *mut u32, u32::from_le_bytes([dw[0], dw[1], dw[2], dw[3]]));
            core::ptr::write_volatile((addr + 4) as *mut u32, u32::from_le_bytes([dw[4], dw[5], dw[6], dw[7]]));
        }
        wait_ready()?;
    }
    f.cr().modify(|w| w.set_pg(false));
    Ok(())
}

fn read(offset: u32, buf: &mut [u8]) {
    for (i, b) in buf.iter_mut().enumerate() {
        // SAFETY: a byte of the store's pages, inside the chip's flash.
        *b = unsafe { core::ptr::read_volatile((FLASH_BASE + offset + i as u32) as *const u8) };
    }
}

impl FlashStore {
    fn page_offset(page: u32) -> u32 {
        STORE_OFFSET + page * PAGE_BYTES
    }

    fn header(&self, page: u32) -> Option<PageHeader> {
        let mut h = [0u8; HEADER_BYTES];
        read(Self::page_offset(page), &mut h);
        let word = |i: usize| u32::from_le_bytes([h[i], h[i + 1], h[i + 2], h[i + 3]]);
        let len = word(8);
        if h[..4] != STORE_MAGIC || len != !word(12) || len as usize > RECORD_MAX {
            return None;
        }
        Some(PageHeader { seq: word(4), len: len as usize })
    }

    /// Pages with a header, newest first.
    fn pages(&self) -> [Option<(u32, PageHeader)>; 2] {
        let a = self.header(0).map(|h| (0, h));
        let b = self.header(1).map(|h| (1, h));
        match (a, b) {
            (Some(x), Some(y)) if y.1.seq.wrapping_sub(x.1.seq) as i32 > 0 => [b, a],
            (None, Some(_)) => [b, None],
            _ => [a, b],
        }
    }

    fn write_page(&mut self, page: u32, seq: u32, record: &[u8]) -> Result<(), FlashError> {
        let base = Self::page_offset(page);
        let len = record.len() as u32;
        let mut h = [0u8; HEADER_BYTES];
        h[..4].copy_from_slice(&STORE_MAGIC);
        h[4..8].copy_from_slice(&seq.to_le_bytes());
        h[8..12].copy_from_slice(&len.to_le_bytes());
        h[12..].copy_from_slice(&(!len).to_le_bytes());
        with_unlocked(|| {
            erase_page(base)?;
            program(base + HEADER_BYTES as u32, record)?;
            program(base, &h)
        })
    }

    /// Whether the record written at `page` reads back as `record`.
    fn verify(&self, page: u32, record: &[u8]) -> bool {
        let mut chunk = [0u8; 32];
        let base = Self::page_offset(page) + HEADER_BYTES as u32;
        record.chunks(chunk.len()).enumerate().all(|(i, want)| {
            let got = &mut chunk[..want.len()];
            read(base + (i * 32) as u32, got);
            got == want
        })
    }
}

impl ParamStore for FlashStore {
    fn save(&mut self, record: &[u8]) -> Result<(), Text> {
        if record.len() > RECORD_MAX {
            return Err(text("record larger than the store's page"));
        }
        if pac::TIM1.bdtr().read().moe() {
            return Err(text("bridge on: flash erase would stall the current loop"));
        }
        let [newest, _] = self.pages();
        let (page, seq) = match newest {
            Some((p, h)) => (1 - p, h.seq.wrapping_add(1)),
            None => (0, 1),
        };
        super::super::watchdog::feed();
        FLASH_STALL.store(true, Ordering::Relaxed);
        let written = self.write_page(page, seq, record);
        FLASH_STALL.store(false, Ordering::Relaxed);
        super::super::watchdog::feed();
        match written {
            Ok(()) if self.verify(page, record) => Ok(()),
            Ok(()) => Err(text("flash: read-back differs from the record written")),
            Err(FlashError) => Err(text("flash: erase or program failed")),
        }
    }

    fn load(&mut self, buf: &mut [u8]) -> Result<usize, Text> {
        let pages = self.pages();
        let mut first: Option<(u32, PageHeader)> = None;
        for (page, h) in pages.into_iter().flatten() {
            let Some(dst) = buf.get_mut(..h.len) else {
                return Err(text("stored record larger than the buffer"));
            };
            read(Self::page_offset(page) + HEADER_BYTES as u32, dst);
            // The newest record that decodes; a torn newer one falls back
            // to the older page.
            if servo_core::params::record::decode(dst).is_ok() {
                return Ok(h.len);
            }
            first.get_or_insert((page, h));
        }
        // None decodes: hand the newest back so the caller reports why.
        match first {
            Some((page, h)) => {
                let dst = buf.get_mut(..h.len).unwrap_or(&mut []);
                read(Self::page_offset(page) + HEADER_BYTES as u32, dst);
                Ok(dst.len())
            }
            None => Ok(0),
        }
    }

    fn observer_staging(&mut self) -> Option<&mut Staging> {
        Some(&mut self.staging)
    }

    fn stored_observer(&mut self) -> Result<Option<&'static Weights>, Text> {
        for (page, h) in self.pages().into_iter().flatten() {
            let base = FLASH_BASE + Self::page_offset(page) + HEADER_BYTES as u32;
            // SAFETY: `h.len` ≤ RECORD_MAX bytes of the store's pages
            // (checked by `header`): mapped, readable flash, written only by
            // `save`, which does not run while this slice lives.
            let bytes = unsafe { core::slice::from_raw_parts(base as *const u8, h.len) };
            // The newest record that decodes, as `load` picks it.
            let Ok(d) = record::decode_record(bytes) else { continue };
            return match d.observer {
                None => Ok(None),
                Some(sec) if sec.weights.is_ok() => {
                    let at = base + sec.words_offset as u32;
                    if at as usize % core::mem::align_of::<Weights>() != 0 {
                        return Err(text("stored observer block not aligned"));
                    }
                    // SAFETY: `decode_record` checked that `WORDS` finite
                    // f32 words start at `at` (aligned, above) and form a
                    // valid block; `Weights` is `repr(C)`, all f32, exactly
                    // those words in that order. The page stays as it is
                    // until a later save erases it, and the server points
                    // the controller elsewhere after each save first.
                    Ok(Some(unsafe { &*(at as *const Weights) }))
                }
                Some(_) => Err(text("stored observer block does not fit this firmware")),
            };
        }
        Ok(None)
    }
}
