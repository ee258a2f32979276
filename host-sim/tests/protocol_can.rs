//! The CAN FD setpoint layout (`protocol::can`): round trips at the layout's
//! resolution, every leg's slot, the stop frame, and corrupt, short, long,
//! foreign and out-of-range frames refused with their reason.

use servo_core::protocol::can::*;

fn sp(position_m: f32, velocity_m_s: f32, force_n: Option<f32>) -> LegSetpoint {
    LegSetpoint { position_m, velocity_m_s, force_n }
}

fn six() -> [Option<LegSetpoint>; LEGS] {
    [
        Some(sp(0.1234567, 0.25, Some(1500.0))),
        Some(sp(-0.01, -0.1, None)),
        Some(sp(0.0, 0.0, Some(-20.5))),
        Some(sp(0.5, 1.0, None)),
        Some(sp(1.999, -7.999, Some(799_999.9))),
        Some(sp(-1.999, 7.999, Some(-799_999.9))),
    ]
}

#[test]
fn setpoints_round_trip_within_one_unit() {
    let legs = six();
    let data = encode_setpoints(42, &legs).expect("encodes");
    assert_eq!(data.len(), SETPOINT_LEN);
    assert_eq!(data[0], KIND_SETPOINTS);
    assert_eq!(data[1], ALL_LEGS);
    assert_eq!(u16::from_le_bytes([data[2], data[3]]), 42);
    let CanMessage::Setpoints { seq, legs: back } = decode(SETPOINT_ID, &data).expect("decodes") else {
        panic!("not setpoints");
    };
    assert_eq!(seq, 42);
    for (a, b) in legs.iter().zip(back.iter()) {
        let (a, b) = (a.unwrap(), b.unwrap());
        // f32 carries ≈ 24 bits: compare at the float's own resolution.
        assert!((a.position_m - b.position_m).abs() <= 1e-9 + a.position_m.abs() * 2e-7, "{a:?} {b:?}");
        assert!((a.velocity_m_s - b.velocity_m_s).abs() <= 1e-6 + a.velocity_m_s.abs() * 2e-7, "{a:?} {b:?}");
        match (a.force_n, b.force_n) {
            (None, None) => {}
            (Some(x), Some(y)) => assert!((x - y).abs() <= 0.1 + x.abs() * 2e-7, "{x} {y}"),
            other => panic!("force presence differs: {other:?}"),
        }
    }
}

#[test]
fn each_drive_takes_its_own_slot() {
    for leg in 0..LEGS {
        let mut legs = [None; LEGS];
        legs[leg] = Some(sp(0.001 * (leg as f32 + 1.0), 0.0, None));
        let data = encode_setpoints(1, &legs).unwrap();
        assert_eq!(data[1], 1 << leg);
        let CanMessage::Setpoints { legs: back, .. } = decode(SETPOINT_ID, &data).unwrap() else { panic!() };
        for other in 0..LEGS as u32 {
            let got = slot(&back, other);
            assert_eq!(got.is_some(), other as usize == leg, "leg {leg}, slot {other}");
        }
        assert!((slot(&back, leg as u32).unwrap().position_m - 0.001 * (leg as f32 + 1.0)).abs() < 1e-8);
    }
    assert_eq!(slot(&six(), 6), None, "no seventh slot");
}

#[test]
fn stop_frame_round_trip() {
    let data = encode_stop(7, 0b10_0001).unwrap();
    assert_eq!(data.len(), STOP_LEN);
    assert_eq!(decode(STOP_ID, &data), Ok(CanMessage::Stop { seq: 7, legs: 0b10_0001 }));
    assert!(names_leg(0b10_0001, 0) && names_leg(0b10_0001, 5) && !names_leg(0b10_0001, 1) && !names_leg(0xFF, 6));
    assert_eq!(encode_stop(0, 0), Err(CanError::LegMask));
    assert_eq!(encode_stop(0, 0x40), Err(CanError::LegMask));
}

#[test]
fn encoder_refuses_what_the_layout_cannot_carry() {
    for (leg, bad) in [
        sp(f32::NAN, 0.0, None),
        sp(2.5, 0.0, None),
        sp(0.0, f32::INFINITY, None),
        sp(0.0, -8.5, None),
        sp(0.0, 0.0, Some(f32::NAN)),
        sp(0.0, 0.0, Some(900_000.0)),
    ]
    .into_iter()
    .enumerate()
    {
        let mut legs = six();
        legs[leg] = Some(bad);
        assert_eq!(encode_setpoints(0, &legs), Err(CanError::OutOfRange { leg: leg as u8 }), "{bad:?}");
    }
    assert_eq!(encode_setpoints(0, &[None; LEGS]), Err(CanError::LegMask));
}

#[test]
fn short_long_foreign_and_corrupt_frames_are_refused() {
    let good = encode_setpoints(3, &six()).unwrap();
    // Every truncation and an extension.
    for n in 0..SETPOINT_LEN {
        assert_eq!(decode(SETPOINT_ID, &good[..n]), Err(CanError::Length), "{n} bytes");
    }
    let mut long = good.to_vec();
    long.push(0);
    assert_eq!(decode(SETPOINT_ID, &long), Err(CanError::Length));
    // Unknown identifiers.
    assert_eq!(decode(0x101, &good), Err(CanError::UnknownId));
    assert_eq!(decode(STOP_ID, &good), Err(CanError::Length));
    // Another kind / layout version.
    let mut k = good;
    k[0] = 0xC3;
    assert_eq!(decode(SETPOINT_ID, &k), Err(CanError::Kind));
    // Mask: reserved bits, empty.
    let mut m = good;
    m[1] |= 0x40;
    assert_eq!(decode(SETPOINT_ID, &m), Err(CanError::LegMask));
    m[1] = 0;
    assert_eq!(decode(SETPOINT_ID, &m), Err(CanError::LegMask));
    // A slot not in the mask must be zero.
    let mut r = good;
    r[1] = ALL_LEGS & !1;
    assert_eq!(decode(SETPOINT_ID, &r), Err(CanError::Reserved));
    // Reserved codes and out-of-range values.
    let mut p = good;
    p[4..8].copy_from_slice(&i32::MIN.to_le_bytes());
    assert_eq!(decode(SETPOINT_ID, &p), Err(CanError::OutOfRange { leg: 0 }));
    let mut p = good;
    p[14..18].copy_from_slice(&2_100_000_000i32.to_le_bytes()); // 2.1 m, leg 1
    assert_eq!(decode(SETPOINT_ID, &p), Err(CanError::OutOfRange { leg: 1 }));
    let mut v = good;
    v[28..31].copy_from_slice(&[0, 0, 0x80]); // velocity "none" code, leg 2
    assert_eq!(decode(SETPOINT_ID, &v), Err(CanError::OutOfRange { leg: 2 }));
    let mut v = good;
    v[38..41].copy_from_slice(&[0x80, 0x96, 0x98]); // −6 777 216 µm/s: in range …
    assert!(decode(SETPOINT_ID, &v).is_ok());
    v[38..41].copy_from_slice(&[0x00, 0x00, 0x7F]); // … 8.32 m/s not
    assert_eq!(decode(SETPOINT_ID, &v), Err(CanError::OutOfRange { leg: 3 }));
    // Stop frame: length, kind, padding.
    let stop = encode_stop(9, ALL_LEGS).unwrap();
    for n in 0..STOP_LEN {
        assert_eq!(decode(STOP_ID, &stop[..n]), Err(CanError::Length));
    }
    let mut s = stop;
    s[7] = 1;
    assert_eq!(decode(STOP_ID, &s), Err(CanError::Reserved));
    let mut s = stop;
    s[0] = KIND_SETPOINTS;
    assert_eq!(decode(STOP_ID, &s), Err(CanError::Kind));
}

#[test]
fn random_bytes_never_panic_and_accepted_frames_re_encode() {
    // A small deterministic generator (no extra dependency).
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let good = encode_setpoints(0, &six()).unwrap();
    let mut accepted = 0;
    for i in 0..200_000 {
        let mut data = good;
        // Flip 1..4 random bits, or fully random data.
        if i % 10 == 0 {
            for b in data.iter_mut() {
                *b = next() as u8;
            }
        } else {
            for _ in 0..(1 + next() % 4) {
                let bit = (next() % (SETPOINT_LEN as u64 * 8)) as usize;
                data[bit / 8] ^= 1 << (bit % 8);
            }
        }
        if let Ok(CanMessage::Setpoints { seq, legs }) = decode(SETPOINT_ID, &data) {
            accepted += 1;
            let again = encode_setpoints(seq, &legs).expect("a decoded frame re-encodes");
            assert!(decode(SETPOINT_ID, &again).is_ok());
        }
    }
    // Bit flips in value bytes stay valid codes (the CAN CRC guards those).
    assert!(accepted > 0);
}

#[test]
fn sequence_order() {
    assert!(is_newer(1, 0));
    assert!(is_newer(0, 0xFFFF), "wraps");
    assert!(!is_newer(5, 5), "a repeat is not newer");
    assert!(!is_newer(4, 5), "an older one is not newer");
}

#[test]
fn leg_index_is_a_validated_parameter() {
    use servo_core::params::{ControlParams, ValidatedParams};
    let mut p = ControlParams::DEFAULT;
    p.stream.leg_index = 5;
    assert!(ValidatedParams::new(p).is_ok());
    p.stream.leg_index = 6;
    let e = ValidatedParams::new(p).unwrap_err();
    assert_eq!(e.field(), "control.stream.leg_index");
}
