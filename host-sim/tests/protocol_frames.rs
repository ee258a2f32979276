//! Protocol framing: round trips, and every corruption refused with its reason.

use servo_core::protocol::*;

fn roundtrip(f: &DriveFrame) -> DriveFrame {
    let mut buf = [0u8; FRAME_MAX];
    let frame = encode(f, &mut buf).expect("fits").to_vec();
    assert_eq!(*frame.last().unwrap(), 0, "ends with the delimiter");
    assert!(!frame[..frame.len() - 1].contains(&0), "COBS leaves no zero inside");
    let mut r = FrameReader::new();
    let mut out = None;
    for &b in &frame {
        if let Feed::Frame(bytes) = r.push(b) {
            out = Some(decode::<DriveFrame>(bytes).expect("decodes"));
        }
    }
    out.expect("a frame")
}

#[test]
fn largest_reply_fits_and_round_trips() {
    let values = heapless::Vec::from_slice(&[1.5f32; CAPTURE_CHUNK_MAX]).unwrap();
    let f = DriveFrame::Reply { seq: 65535, reply: Reply::CaptureData { signal: 3, start: 999, values } };
    assert_eq!(roundtrip(&f), f);
}

#[test]
fn a_flipped_bit_is_a_crc_error_not_a_message() {
    let req = RequestFrame { seq: 7, request: Request::ParamGet { index: servo_core::leaf!(speed_pi.kp) } };
    let mut buf = [0u8; FRAME_MAX];
    let frame = encode(&req, &mut buf).unwrap().to_vec();
    let mut crc_errors = 0;
    for i in 0..frame.len() - 1 {
        for bit in 0..8 {
            let mut f = frame[..frame.len() - 1].to_vec();
            f[i] ^= 1 << bit;
            match decode::<RequestFrame>(&mut f) {
                Ok(m) => panic!("byte {i} bit {bit}: corrupted frame decoded as {m:?}"),
                Err(FrameError::Crc) => crc_errors += 1,
                Err(_) => {}
            }
        }
    }
    assert!(crc_errors > 0);
}

#[test]
fn a_refusal_reason_crosses_as_a_code_and_reads_as_its_text() {
    use servo_core::protocol::Reason;
    let frame = DriveFrame::Reply { seq: 3, reply: Reply::Error(Error::Stream { reason: Reason::StreamJump }) };
    let mut buf = [0u8; FRAME_MAX];
    let bytes = encode(&frame, &mut buf).unwrap().to_vec();
    let mut body = bytes[..bytes.len() - 1].to_vec();
    let back: DriveFrame = decode(&mut body).unwrap();
    assert_eq!(back, frame);
    let DriveFrame::Reply { reply: Reply::Error(Error::Stream { reason }), .. } = back else { panic!() };
    assert_eq!(reason.to_string(), "jump beyond control.trajectory.max_velocity_m_s since the last point");
}
