//! The transports' rates and buffer sizes, and the USART2 transmit
//! queue's one rule: a frame goes in whole or not at all, without waiting.
//! Kept free of the HAL so that firmware-tests' comms test runs the same
//! code on the same sizes.

use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::pipe::Pipe;

/// USART2 baud rate. The ST-LINK/V2-1's bridge (an STM32F103 at 72 MHz)
/// makes 921 600 Bd as 72 MHz / (16 × 4.875) = 923 077 Bd (+0.16 %), this
/// USART as 170 MHz / 184 = 923 913 Bd (+0.25 %): 0.09 % apart, far inside
/// the ±2 % an 8N1 frame tolerates. ≈ 92 kB/s: a 1 kHz telemetry frame of
/// 17 fields (≈ 80 bytes) fits.
pub const BAUD: u32 = 921_600;

/// Bytes the main task may queue before the writer task has sent them: a
/// reply (≤ `FRAME_MAX` = 320 bytes) and a telemetry frame (≈ 110 bytes)
/// at once, the most the request–reply protocol has in flight.
pub const TX_QUEUE_LEN: usize = 512;

/// USART2 receive ring (DMA, circular): 5.6 ms of bytes at 921 600 Bd
/// (docs/firmware-comms.md, *USART2*).
pub const RX_RING_LEN: usize = 512;

/// FDCAN1's receive FIFO 0 on the STM32G4: three frames (fixed by the
/// message RAM layout, RM0440); a fourth arriving before one is read is lost.
/// (Hardware: the firmware never reads it; the comms model does.)
#[allow(dead_code)]
pub const CAN_RX_FIFO_FRAMES: usize = 3;

/// Puts `bytes` into `queue` whole, or nothing if it has no room (the
/// caller counts and reports the drop). Never waits. Sound as long as one
/// context writes (the main task): the room checked is still there.
pub fn queue_whole<M: RawMutex, const N: usize>(queue: &Pipe<M, N>, bytes: &[u8]) -> bool {
    if bytes.is_empty() {
        return true;
    }
    if queue.free_capacity() < bytes.len() {
        return false;
    }
    // A write stops at the ring's end: write on until all of it is in
    // (the room is there, so each write takes at least one byte).
    let mut rest = bytes;
    while !rest.is_empty() {
        match queue.try_write(rest) {
            Ok(n) if n > 0 => rest = rest.get(n..).unwrap_or(&[]),
            _ => return false,
        }
    }
    true
}
