//! The drive protocol: one definition for the firmware (USART2, FDCAN1), the
//! simulated drive (host-sim over TCP) and the host tool.
//!
//! - `messages`: what may be asked and answered ([`RequestFrame`],
//!   [`DriveFrame`]);
//! - `can`: the six legs' setpoint stream over CAN FD (fixed layout);
//! - `frame`: postcard + CRC-32 + COBS framing, and the byte-stream reader;
//! - `params`: parameters by dotted path (`control.speed_pi.kp`);
//! - `observer`: the observer weight block's upload, storage and status;
//! - `drive`: what the server needs of a drive ([`DriveAccess`]) and of a
//!   store ([`ParamStore`]);
//! - `server`: request in, reply out ([`Server`]).
//!
//! Versioning: [`SCHEMA_HASH`] is the postcard-schema hash of the message
//! types and of `ControlParams` (whose leaves are the parameter paths and the
//! flash record). `Info` carries it; a host refuses a drive whose hash
//! differs from its own, and a flash record carries [`PARAMS_SCHEMA_HASH`].

pub mod can;
pub mod drive;
pub mod frame;
pub mod messages;
pub mod observer;
pub mod params;
pub mod server;

pub use frame::{decode, encode, Feed, FrameReader, FRAME_MAX};
pub use drive::{CaptureReply, DriveAccess, DriveStatus, ParamStore};
pub use messages::*;
// The core's words the messages carry, re-exported for the protocol's users.
pub use crate::capture::{CaptureConfig, CaptureRequest, CaptureState, CaptureStatus, CaptureTrigger, Signal, SignalList, CAPTURE_SIGNALS_MAX};
pub use crate::params::record::PARAMS_SCHEMA_HASH;
pub use crate::params::value::{Value, ValueKind};
pub use crate::reason::Reason;
pub use crate::test_signals::{ChirpTarget, TestSignal};
pub use server::{Identity, Server};
/// The fixed-capacity types in the messages, at the version they use.
pub use heapless;

use crate::params::ControlParams;
use postcard_schema::key::Key;

/// Protocol version for humans; compatibility is decided by the hash.
pub const PROTOCOL_VERSION: u16 = 1;

/// Hash of everything both ends must agree on.
pub const SCHEMA_HASH: [u8; 8] =
    Key::for_path::<(RequestFrame, DriveFrame, ControlParams)>("cylinder-servo/protocol").to_bytes();
