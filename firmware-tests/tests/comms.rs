//! The main task's transports under load: the platform's six-leg CAN
//! setpoint frame every millisecond while the host keeps USART2 replying at
//! its full rate (a request as soon as the previous reply has arrived,
//! every reply a full `FRAME_MAX` frame). No CAN frame may be lost.
//!
//! A time-stepped model (1 µs) of the main task's event loop, with the
//! firmware's own sizes and rule (`src/board/b_g431b_esc1/comms_sizes.rs`,
//! included here: baud rate, receive ring, transmit queue, the FDCAN FIFO's
//! three frames, `queue_whole` on a real `embassy_sync::pipe::Pipe`):
//! - FDCAN1's FIFO 0 takes a frame each millisecond; a frame arriving with
//!   three unread is lost (as the hardware does);
//! - the main task serves one ready event at a time, CAN first, then up to
//!   64 received bytes, then its 50 Hz tick; each costs an upper bound of
//!   its handling time on the board (below), during which nothing else runs;
//! - a complete request is answered by putting the reply into the transmit
//!   queue (`queue_whole`); the writer task, when the main task yields,
//!   hands the queue to the line in 64-byte chunks at 921 600 Bd;
//! - for contrast, the same loop awaiting each reply's transmission inside
//!   its arm (what the firmware did before the writer task) must lose
//!   frames, or the model would not show what the queue is for.
#![no_std]
#![no_main]

use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use embassy_sync::pipe::Pipe;
use firmware_tests::{check, test_main, Outcome};
use servo_core::protocol::FRAME_MAX;

#[path = "../../src/board/b_g431b_esc1/comms_sizes.rs"]
mod comms_sizes;
use comms_sizes::{queue_whole, BAUD, CAN_RX_FIFO_FRAMES, RX_RING_LEN, TX_QUEUE_LEN};

const NS_PER_US: u64 = 1_000;
/// One 8N1 character (10 bits) on the line.
const BYTE_NS: u64 = 10 * 1_000_000_000 / BAUD as u64;
/// The platform's setpoint frame period (1 kHz).
const CAN_PERIOD_NS: u64 = 1_000 * NS_PER_US;
/// Upper bounds of the main task's handling times on the board (170 MHz):
/// a CAN frame is decoded and handed to the server, which asks the PWM
/// interrupt through the link (`ServoBoard::call` gives up after four PWM
/// periods, 200 µs); a request the same, plus encoding the reply.
const CAN_HANDLING_NS: u64 = 250 * NS_PER_US;
const REQUEST_HANDLING_NS: u64 = 250 * NS_PER_US;
/// Per received byte fed to the frame reader.
const BYTE_HANDLING_NS: u64 = NS_PER_US;
/// The 50 Hz tick: snapshot, button, LED, log lines.
const TICK_PERIOD_NS: u64 = 20_000 * NS_PER_US;
const TICK_HANDLING_NS: u64 = 300 * NS_PER_US;
/// How much the main task takes from the receive ring per read.
const READ_CHUNK: usize = 64;
/// A short request (a parameter read, a status): its reply is a full frame.
const REQUEST_LEN: usize = 16;
const REPLY_LEN: usize = FRAME_MAX;
const SIMULATED_NS: u64 = 2_000_000 * NS_PER_US;

#[derive(Clone, Copy, PartialEq)]
enum Replies {
    /// Into the transmit queue, sent by the writer task (the firmware).
    Queued,
    /// Awaited inside the arm that received the request.
    Awaited,
}

#[derive(Default)]
struct Counts {
    can_sent: u32,
    can_received: u32,
    can_lost: u32,
    requests: u32,
    replies_delivered: u32,
    replies_dropped: u32,
    rx_overrun_bytes: u32,
    longest_busy_ns: u64,
}

fn run(replies: Replies) -> Counts {
    let queue: Pipe<NoopRawMutex, TX_QUEUE_LEN> = Pipe::new();
    let reply = [0x5Au8; REPLY_LEN];
    let mut c = Counts::default();
    let mut fifo = 0usize;
    let mut next_can = 0u64;
    let mut next_tick = TICK_PERIOD_NS;
    let mut tick_pending = false;
    // Main task: busy until; bytes of the request being assembled.
    let mut busy_until = 0u64;
    let mut request_bytes = 0usize;
    // USART2 receive: the ring's fill, the host's request bytes still to send.
    let mut ring = 0usize;
    let mut host_to_send = REQUEST_LEN;
    let mut next_rx_byte = 0u64;
    // USART2 transmit: the line is busy until; bytes of the reply the host
    // still waits for.
    let mut line_free = 0u64;
    let mut line_bytes_in_flight = 0usize;
    let mut reply_left = 0usize;
    let mut t = 0u64;
    while t < SIMULATED_NS {
        if t >= next_can {
            c.can_sent += 1;
            if fifo < CAN_RX_FIFO_FRAMES {
                fifo += 1;
            } else {
                c.can_lost += 1;
            }
            next_can += CAN_PERIOD_NS;
        }
        if t >= next_tick {
            tick_pending = true;
            next_tick += TICK_PERIOD_NS;
        }
        if host_to_send > 0 && t >= next_rx_byte {
            host_to_send -= 1;
            if ring < RX_RING_LEN {
                ring += 1;
            } else {
                c.rx_overrun_bytes += 1;
            }
            next_rx_byte = t + BYTE_NS;
        }
        // The line finishes a chunk: its bytes reach the host.
        if line_bytes_in_flight > 0 && t >= line_free {
            let n = line_bytes_in_flight.min(reply_left);
            reply_left -= n;
            line_bytes_in_flight = 0;
            if reply_left == 0 && n > 0 {
                c.replies_delivered += 1;
                // The host sends its next request at once: full rate.
                host_to_send = REQUEST_LEN;
                next_rx_byte = t;
            }
        }
        if t >= busy_until {
            // The writer task runs when the main task yields.
            if replies == Replies::Queued && line_bytes_in_flight == 0 && t >= line_free {
                let mut chunk = [0u8; 64];
                if let Ok(n) = queue.try_read(&mut chunk) {
                    line_bytes_in_flight = n;
                    line_free = t + n as u64 * BYTE_NS;
                }
            }
            let start = t;
            if fifo > 0 {
                fifo -= 1;
                c.can_received += 1;
                busy_until = t + CAN_HANDLING_NS;
            } else if ring > 0 {
                let n = ring.min(READ_CHUNK);
                ring -= n;
                busy_until = t + n as u64 * BYTE_HANDLING_NS;
                request_bytes += n;
                if request_bytes >= REQUEST_LEN {
                    request_bytes -= REQUEST_LEN;
                    c.requests += 1;
                    busy_until += REQUEST_HANDLING_NS;
                    reply_left += REPLY_LEN;
                    match replies {
                        Replies::Queued => {
                            if !queue_whole(&queue, &reply) {
                                c.replies_dropped += 1;
                                reply_left -= REPLY_LEN;
                            }
                        }
                        Replies::Awaited => {
                            // `tx.write(reply).await` in the arm: the task
                            // resumes when the last byte is on the line.
                            let on_line = busy_until.max(line_free);
                            line_free = on_line + REPLY_LEN as u64 * BYTE_NS;
                            line_bytes_in_flight = REPLY_LEN;
                            busy_until = line_free;
                        }
                    }
                }
            } else if tick_pending {
                tick_pending = false;
                busy_until = t + TICK_HANDLING_NS;
            }
            c.longest_busy_ns = c.longest_busy_ns.max(busy_until.saturating_sub(start));
        }
        t += NS_PER_US;
    }
    c
}

/// The firmware's loop: every setpoint frame read, every reply delivered.
fn can_frames_not_starved_by_uart_replies() -> Outcome {
    let c = run(Replies::Queued);
    cortex_m_semihosting::hprintln!(
        "  queued replies: {} CAN frames sent, {} received, {} lost; {} requests, {} replies delivered, {} dropped; longest busy stretch {} us",
        c.can_sent,
        c.can_received,
        c.can_lost,
        c.requests,
        c.replies_delivered,
        c.replies_dropped,
        c.longest_busy_ns / NS_PER_US
    );
    check!(c.can_sent >= 1_999, "{} frames sent", c.can_sent);
    check!(c.can_lost == 0, "{} CAN frames lost", c.can_lost);
    check!(c.can_received + 3 >= c.can_sent, "{} of {} received", c.can_received, c.can_sent);
    check!(c.replies_dropped == 0, "{} replies dropped by the transmit queue", c.replies_dropped);
    check!(c.rx_overrun_bytes == 0, "{} bytes lost by the receive ring", c.rx_overrun_bytes);
    // The line stays the bottleneck: at most one 336-byte exchange per
    // 3.6 ms; the writer loses a little where a 64-byte chunk ends while
    // the main task handles a frame (it starts the next when the task
    // yields). At least 85 % of the line's bound.
    let line_bound = (SIMULATED_NS / ((REPLY_LEN + REQUEST_LEN) as u64 * BYTE_NS)) as u32;
    cortex_m_semihosting::hprintln!("  replies: {} of the line's bound {}", c.replies_delivered, line_bound);
    check!(c.replies_delivered * 100 >= line_bound * 85, "{} replies, the line allows {}", c.replies_delivered, line_bound);
    Ok(())
}

/// The same load with each reply awaited in its arm loses setpoint frames:
/// the model sees what the writer task removes.
fn awaiting_replies_in_the_loop_loses_frames() -> Outcome {
    let c = run(Replies::Awaited);
    cortex_m_semihosting::hprintln!(
        "  awaited replies: {} CAN frames sent, {} lost; longest busy stretch {} us",
        c.can_sent,
        c.can_lost,
        c.longest_busy_ns / NS_PER_US
    );
    check!(c.can_lost > 100, "only {} frames lost", c.can_lost);
    Ok(())
}

test_main!(can_frames_not_starved_by_uart_replies, awaiting_replies_in_the_loop_loses_frames);
