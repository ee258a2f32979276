//! 10⁶ random and mutated frames through FrameReader → decode →
//! Server::handle with a mock drive: nothing panics, every reply fits a
//! frame and echoes the seq, bad frames are answered with seq 0, and a
//! request that decodes is applied whole or not at all.
//!
//! proptest's runner draws 1000 seeds; each seed drives 1000 frames from a ChaCha
//! generator (valid requests, bit flips, truncations, insertions, splices,
//! garbage), so the run stays in seconds while covering 10⁶ frames.

mod protocol_support;

use proptest::prelude::*;
use protocol_support::*;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use servo_core::params::{leaves, ValidatedParams};
use servo_core::protocol::params as paths;
use servo_core::protocol::*;
use servo_core::{Command, CommandError, Mode};
use std::sync::atomic::{AtomicU64, Ordering};

const SEEDS: u32 = 1000;
const FRAMES_PER_SEED: usize = 1000;
static FRAMES: AtomicU64 = AtomicU64::new(0);
static DECODED: AtomicU64 = AtomicU64::new(0);
static APPLIED: AtomicU64 = AtomicU64::new(0);

fn random_f32(rng: &mut ChaCha8Rng, around: f32) -> f32 {
    match rng.random_range(0..10) {
        0 => f32::NAN,
        1 => f32::INFINITY,
        2 => f32::from_bits(rng.next_u32()),
        3 => -around,
        _ => around * rng.random_range(0.5..2.0),
    }
}

fn random_request(rng: &mut ChaCha8Rng, d: &MockDrive) -> Request {
    let leaf = |rng: &mut ChaCha8Rng| rng.random_range(0..paths::PARAM_COUNT) as u16;
    match rng.random_range(0..20) {
        0 => Request::Info,
        1 => Request::Status,
        2 => Request::ParamCount,
        3 => Request::ParamGet { index: rng.random_range(0..200) },
        4 => Request::ParamGet { index: leaf(rng) },
        5..=8 => {
            let index = if rng.random_range(0..10) == 0 { rng.random_range(paths::PARAM_COUNT as u16..=u16::MAX) } else { leaf(rng) };
            let value = match leaves::get(&d.params, usize::from(index)).ok_or(()) {
                Ok(Value::F32(v)) if rng.random_range(0..8) > 0 => Value::F32(random_f32(rng, v)),
                Ok(Value::U32(v)) if rng.random_range(0..8) > 0 => Value::U32(v.saturating_add(rng.random_range(0..3)).saturating_sub(1)),
                Ok(Value::I32(v)) if rng.random_range(0..8) > 0 => Value::I32(if rng.random() { -v } else { v }),
                Ok(Value::Bool(v)) => Value::Bool(!v),
                Ok(Value::Variant(_)) => Value::Variant(rng.random_range(0..3)),
                _ => Value::U32(rng.next_u32()),
            };
            Request::ParamSet { index, value }
        }
        9 => Request::Save,
        10 => Request::Load,
        11 => Request::Defaults,
        12 => Request::Command(match rng.random_range(0..6) {
            0 => DriveCommand::Enable,
            1 => DriveCommand::Disable,
            2 => DriveCommand::Stop,
            3 => DriveCommand::MoveTo { position_m: random_f32(rng, 0.3) },
            4 => DriveCommand::ClearFaults,
            _ => DriveCommand::SetPositionShift { shift_m: random_f32(rng, 1e-4) },
        }),
        13..=16 => Request::Stream(StreamPoint {
            position_m: d.position_reference_m + rng.random_range(-3e-4..3e-4) * if rng.random_range(0..20) == 0 { 100.0 } else { 1.0 },
            velocity_m_s: random_f32(rng, 0.1),
            force_n: if rng.random() { None } else { Some(random_f32(rng, 100.0)) },
        }),
        17 => Request::Telemetry { fields: rng.next_u32() >> rng.random_range(0..32), rate_hz: rng.random_range(0..2000) },
        18 => Request::Capture(CaptureRequest::Read { signal: rng.random(), start: rng.random(), count: rng.random() }),
        _ => Request::Test(TestSignal::SpeedStep { amplitude_rad_s: random_f32(rng, 10.0), duration_s: random_f32(rng, 0.1) }),
    }
}

/// One encoded request (delimiter included), then mutated.
fn random_bytes(rng: &mut ChaCha8Rng, d: &MockDrive, spare: &[u8]) -> Vec<u8> {
    let mut buf = [0u8; FRAME_MAX];
    let req = RequestFrame { seq: rng.random(), request: random_request(rng, d) };
    let mut f = encode(&req, &mut buf).unwrap().to_vec();
    match rng.random_range(0..10) {
        // Unchanged: the valid requests must be exercised too.
        0..=3 => {}
        4 => {
            for _ in 0..rng.random_range(1..4) {
                let i = rng.random_range(0..f.len());
                f[i] ^= 1 << rng.random_range(0..8);
            }
        }
        5 => f.truncate(rng.random_range(0..f.len())),
        6 => {
            for _ in 0..rng.random_range(1..4) {
                let i = rng.random_range(0..=f.len());
                f.insert(i, rng.random());
            }
        }
        7 if !spare.is_empty() => {
            // Splice: a head of this frame, a tail of the previous one.
            let a = rng.random_range(0..f.len());
            let b = rng.random_range(0..spare.len());
            f.truncate(a);
            f.extend_from_slice(&spare[b..]);
        }
        8 => {
            let n = rng.random_range(0..400);
            f = (0..n).map(|_| rng.random()).collect();
        }
        _ => {
            let i = rng.random_range(0..f.len());
            f.remove(i);
        }
    }
    f
}

fn check_frame(srv: &mut Server, d: &mut MockDrive, s: &mut MemStore, bytes: &[u8]) {
    let mut copy = bytes.to_vec();
    let mut out = [0u8; FRAME_MAX];
    let req = match decode::<RequestFrame>(&mut copy) {
        Err(e) => {
            let mut again = bytes.to_vec();
            let before = (d.params, d.commands.len(), d.applied);
            let r = srv.handle_bytes(&mut again, d, s);
            assert_eq!(r, Some(DriveFrame::Reply { seq: 0, reply: Reply::Error(Error::Frame(e)) }));
            assert_eq!(before, (d.params, d.commands.len(), d.applied), "a bad frame changed nothing");
            return;
        }
        Ok(req) => req,
    };
    DECODED.fetch_add(1, Ordering::Relaxed);
    let (params, commands, applied) = (d.params, d.commands.len(), d.applied);
    let reply = srv.handle(&req, d, s);
    if let Some(f) = &reply {
        assert!(encode(f, &mut out).is_some(), "reply fits a frame: {f:?}");
        assert!(matches!(f, DriveFrame::Reply { seq, .. } if *seq == req.seq));
    }
    let reply = reply.map(|f| match f {
        DriveFrame::Reply { reply, .. } => reply,
        DriveFrame::Telemetry(_) => panic!("telemetry as a reply"),
    });
    let refused = matches!(reply, Some(Reply::Error(_)));
    // The drive's parameters are always a valid, finite set.
    assert!(ValidatedParams::new(d.params).is_ok());
    match &req.request {
        Request::ParamSet { index, value } => {
            if refused {
                assert_eq!((d.params, d.applied), (params, applied), "{req:?} → {reply:?}: nothing applied");
            } else {
                let mut expected = params;
                leaves::set(&mut expected, usize::from(*index), *value).unwrap();
                assert_eq!(d.params, expected, "{req:?}: exactly the one leaf");
                assert_eq!(d.applied, applied + 1);
                APPLIED.fetch_add(1, Ordering::Relaxed);
            }
        }
        Request::Load | Request::Defaults => {
            if refused {
                assert_eq!(d.params, params);
            }
        }
        Request::Stream(_) => {
            assert_eq!(d.params, params);
            if refused {
                assert_eq!(d.commands.len(), commands, "{req:?}: refused, not passed on");
            } else {
                assert!(reply.is_none());
                assert!(matches!(d.commands.last(), Some(Command::Stream { .. })));
                assert_eq!(d.commands.len(), commands + 1);
            }
        }
        _ => assert_eq!((d.params, d.applied), (params, applied), "{req:?} changed parameters"),
    }
    if !matches!(req.request, Request::Stream(_)) {
        assert!(reply.is_some(), "{req:?}: every request but a stream point is answered");
    }
}

fn run_seed(seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut srv = server();
    let mut d = MockDrive::new();
    let mut s = MemStore::default();
    let mut reader = FrameReader::new();
    let mut spare = vec![];
    for _ in 0..FRAMES_PER_SEED {
        d.time_s += rng.random_range(0.0..0.004);
        if rng.random_range(0..50) == 0 {
            d.refuse = Some(CommandError::NotRunning);
        }
        if rng.random_range(0..100) == 0 && !s.record.is_empty() {
            let i = rng.random_range(0..s.record.len());
            s.record[i] ^= 0x20;
        }
        let bytes = random_bytes(&mut rng, &d, &spare);
        FRAMES.fetch_add(1, Ordering::Relaxed);
        for &b in &bytes {
            match reader.push(b) {
                servo_core::protocol::Feed::Frame(f) => {
                    let f = f.to_vec();
                    check_frame(&mut srv, &mut d, &mut s, &f);
                }
                servo_core::protocol::Feed::Dropped(e) => assert_eq!(e, FrameError::TooLong),
                servo_core::protocol::Feed::Pending => {}
            }
        }
        // End every mutated frame: the next starts clean, as after a
        // receiver's resynchronisation.
        if let servo_core::protocol::Feed::Frame(f) = reader.push(0) {
            let f = f.to_vec();
            check_frame(&mut srv, &mut d, &mut s, &f);
        }
        spare = bytes;
        assert!(matches!(d.mode, Mode::Disabled | Mode::Running));
    }
}

#[test]
fn a_million_random_and_mutated_frames() {
    let config = ProptestConfig { cases: SEEDS, failure_persistence: None, ..ProptestConfig::default() };
    let mut runner = proptest::test_runner::TestRunner::new(config);
    let t = std::time::Instant::now();
    let result = runner.run(&any::<u64>(), |seed| {
        run_seed(seed);
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    let (frames, decoded, applied) = (FRAMES.load(Ordering::Relaxed), DECODED.load(Ordering::Relaxed), APPLIED.load(Ordering::Relaxed));
    println!(
        "{frames} frames ({SEEDS} seeds × {FRAMES_PER_SEED}) in {:.2} s: {decoded} decoded and handled, {applied} parameter sets applied",
        t.elapsed().as_secs_f64()
    );
    assert!(frames >= 1_000_000);
    assert!(decoded > 300_000 && applied > 10_000, "valid requests exercised");
}
