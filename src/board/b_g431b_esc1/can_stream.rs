//! The CAN setpoint stream's receiving side: each frame decoded and
//! checked whole (`protocol::can`), kept in sequence, and this leg's slot
//! handed to the server like a `Stream` request; counters for the
//! heartbeat.

use core::borrow::Borrow;

use defmt::warn;
use embassy_time::{Duration, Instant};
use servo_core::params::ValidatedParams;
use servo_core::protocol::{self as proto, can, DriveCommand, DriveFrame, ParamStore, RequestFrame, Server, StreamPoint};

/// No CAN setpoint frame for this long: the next one may restart the
/// sequence count (the platform controller restarted).
const CAN_SEQ_RESET: Duration = Duration::from_millis(100);

/// The CAN setpoint stream's receiving side: sequence order and counters.
#[derive(Default)]
pub struct CanStream {
    pub last_seq: Option<u16>,
    pub last_at: Option<Instant>,
    pub accepted: u32,
    pub refused: u32,
    pub stale: u32,
    pub bad: u32,
    pub other_legs: u32,
    pub bus_errors: u32,
}

impl CanStream {
    /// One frame: decoded and checked whole (`protocol::can`), in sequence,
    /// then this leg's slot goes the way of `Request::Stream` (the server's
    /// stream checks), a stop frame naming this leg the way of
    /// `DriveCommand::Stop`.
    pub fn receive<P: Borrow<ValidatedParams>, D: proto::DriveAccess, S: ParamStore>(
        &mut self,
        id: u16,
        data: &[u8],
        leg: u32,
        server: &mut Server<P>,
        drive: &mut D,
        store: &mut S,
    ) {
        let message = match can::decode(id, data) {
            Ok(m) => m,
            Err(e) => {
                self.bad = self.bad.wrapping_add(1);
                if self.bad.is_power_of_two() {
                    warn!("CAN frame 0x{=u16:x} refused: {} ({=u32} so far)", id, e, self.bad);
                }
                return;
            }
        };
        let now = Instant::now();
        let fresh = self.last_at.is_none_or(|t| now - t > CAN_SEQ_RESET);
        if let (Some(last), false) = (self.last_seq, fresh) {
            if !can::is_newer(message.seq(), last) {
                self.stale = self.stale.wrapping_add(1);
                return;
            }
        }
        self.last_seq = Some(message.seq());
        self.last_at = Some(now);
        let request = match message {
            can::CanMessage::Setpoints { legs, .. } => match can::slot(&legs, leg) {
                Some(sp) => proto::Request::Stream(StreamPoint {
                    position_m: sp.position_m,
                    velocity_m_s: sp.velocity_m_s,
                    force_n: sp.force_n,
                }),
                None => {
                    self.other_legs = self.other_legs.wrapping_add(1);
                    return;
                }
            },
            can::CanMessage::Stop { legs, .. } => {
                if !can::names_leg(legs, leg) {
                    self.other_legs = self.other_legs.wrapping_add(1);
                    return;
                }
                self.last_seq = None;
                proto::Request::Command(DriveCommand::Stop)
            }
        };
        let frame = RequestFrame { seq: 0, request };
        match server.handle(&frame, drive, store) {
            Some(DriveFrame::Reply { reply: proto::Reply::Error(e), .. }) => {
                self.refused = self.refused.wrapping_add(1);
                if self.refused.is_power_of_two() {
                    // The reason by its code's name (defmt: no text in flash).
                    match &e {
                        proto::Error::Stream { reason } => warn!("CAN setpoint refused ({=u32} so far): {}", self.refused, reason),
                        _ => warn!("CAN stop refused ({=u32} so far)", self.refused),
                    }
                }
            }
            _ => self.accepted = self.accepted.wrapping_add(1),
        }
    }
}
