//! The observer's weights as a parameter block: checked whole (shape,
//! finite, structure hash, normalisation, shift bound), kept in the flash
//! record beside the parameters (version 3; version 2 still read), uploaded
//! over the protocol in chunks, and run bit for bit as the same weights
//! compiled in.

mod drive_support;
mod protocol_support;

use host_sim::config::RigConfig;
use drive_support::Drive;
use host_sim::drive::{self, DriveOptions};
use host_sim::tool::observer as obs;
use protocol_support::*;
use servo_core::observer::block::{self, ForceSource, Part, Weights, STRUCTURE_HASH, WORDS_STATIC as WORDS};
use servo_core::observer::model::{HIDDEN, INPUTS};

/// The compiled model in the drive's five-slot network (its fifth input
/// unused), as the drive runs it.
const MODEL: Weights = servo_core::observer::lift(&servo_core::observer::model::MODEL);

/// `m`'s words as a four-input block (what a host uploads for it).
fn words4(m: &Weights) -> Vec<f32> {
    let (w, n) = block::to_block_words(m, INPUTS);
    w[..n].to_vec()
}
use servo_core::observer::{evaluate, log2_decay};
use servo_core::params::record::{self, RecordError, RECORD_MAX};
use servo_core::protocol::{self as proto, DriveCommand, Error, ObserverRequest, ObserverSource, Reply, Request};
use servo_core::{ControlParams, Reason};

const SHIFT_MAX_M: f32 = ControlParams::DEFAULT.faults.observer_shift_max_m;

fn validate(words: &[f32]) -> Result<Weights, block::BlockError> {
    block::validate(INPUTS as u16, HIDDEN as u16, &STRUCTURE_HASH, words, SHIFT_MAX_M, ForceSource::LoadCell)
}

/// A model other than the compiled one that still passes every check: the
/// output weights scaled by 0.9 (the prediction stays within the bound).
fn other_model() -> Weights {
    let mut m = MODEL;
    for w in m.weights.iter_mut() {
        *w *= 0.9;
    }
    m
}

/// Inputs over and beyond the trained range, as a drive meets them.
fn input_grid() -> Vec<[f32; servo_core::observer::NETWORK_INPUTS]> {
    let mut out = Vec::new();
    let n = 7;
    for a in 0..n {
        for b in 0..n {
            for c in 0..n {
                let f = |k: usize, j: usize| {
                    let (lo, hi) = (MODEL.input_min[j], MODEL.input_max[j]);
                    lo + (hi - lo) * (k as f32 / (n - 1) as f32 * 1.2 - 0.1)
                };
                // Speed and nut speed tied through the lead, as on the drive.
                let speed = f(a, 0);
                // The direction of travel as the drive feeds it: a model
                // without the fifth input must not hear it.
                let travel = (a % 3) as f32 - 1.0;
                out.push([speed, speed * 0.005 / std::f32::consts::TAU, f(b, 2), f(c, 3), travel]);
            }
        }
    }
    out
}

#[test]
fn the_compiled_model_passes_its_own_checks_and_words_round_trip() {
    let words = words4(&MODEL);
    assert_eq!(words.len(), WORDS);
    let back = validate(&words).expect("the shipped model is a valid block");
    assert_eq!(back, MODEL);
    // The decays the generator writes are the ones the check expects.
    for (k, &s) in MODEL.widths.iter().enumerate() {
        assert_eq!(MODEL.log2_decay[k].to_bits(), log2_decay(s).to_bits());
    }
    // Every word lands in the part its name says.
    assert_eq!(block::part_of(0, INPUTS), (Part::InputMin, 0));
    assert_eq!(block::part_of(3 * INPUTS, INPUTS), (Part::Centres, 0));
    assert_eq!(block::part_of(WORDS - 1, INPUTS), (Part::OutputOffset, 0));
    assert_eq!(words[WORDS - 3].to_bits(), MODEL.bias.to_bits());
    assert_eq!(words[3 * INPUTS + INPUTS + 2].to_bits(), MODEL.centres[1][2].to_bits());
}

#[test]
fn bad_blocks_are_refused_naming_the_part() {
    let good = words4(&MODEL);
    let refuse = |words: &[f32]| validate(words).unwrap_err();
    // Shape.
    let e = block::validate(INPUTS as u16 + 2, HIDDEN as u16, &STRUCTURE_HASH, &good, SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!((e.part, e.reason), (Part::Shape, Reason::ObserverInputCount));
    // Five inputs is a shape the drive takes, but not with four inputs' words.
    let e = block::validate(INPUTS as u16 + 1, HIDDEN as u16, &STRUCTURE_HASH, &good, SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!((e.part, e.reason), (Part::Shape, Reason::ObserverWordCount));
    let e = block::validate(INPUTS as u16, 32, &STRUCTURE_HASH, &good, SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!((e.part, e.reason), (Part::Shape, Reason::ObserverHiddenCount));
    assert_eq!(refuse(&good[..WORDS - 1]).reason, Reason::ObserverWordCount);
    // Structure hash.
    let mut h = STRUCTURE_HASH;
    h[7] ^= 1;
    let e = block::validate(INPUTS as u16, HIDDEN as u16, &h, &good, SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!(e.part, Part::StructureHash);
    // NaN and infinity, named by part and element.
    for (i, bad) in [(5usize, f32::NAN), (3 * INPUTS + 9, f32::INFINITY), (WORDS - 3, f32::NEG_INFINITY)] {
        let mut w = good.clone();
        w[i] = bad;
        let e = refuse(&w);
        let (part, k) = block::part_of(i, INPUTS);
        assert_eq!((e.part, usize::from(e.index), e.reason), (part, k, Reason::MustBeFinite), "word {i}");
    }
    // Normalisation: a scale that is not the range's.
    let mut m = MODEL;
    m.input_scale[2] *= 1.01;
    let e = refuse(&words4(&m));
    assert_eq!((e.part, e.index, e.reason), (Part::InputScale, 2, Reason::ObserverScaleMismatch));
    let mut m = MODEL;
    m.input_max[1] = m.input_min[1];
    assert_eq!(refuse(&words4(&m)).part, Part::InputMax);
    let mut m = MODEL;
    m.log2_decay[4] *= 0.5;
    let e = refuse(&words4(&m));
    assert_eq!((e.part, e.index), (Part::Log2Decay, 4));
    let mut m = MODEL;
    m.widths[0] = -m.widths[0];
    assert_eq!(refuse(&words4(&m)).part, Part::Widths);
    // The shift: a model predicting 10 × the error breaks the bound.
    let mut m = MODEL;
    m.output_scale *= 10.0;
    let e = refuse(&words4(&m));
    assert_eq!((e.part, e.reason), (Part::Prediction, Reason::ObserverShiftBeyondBound));
    let mut m = MODEL;
    m.output_offset = 0.01;
    assert_eq!(refuse(&words4(&m)).part, Part::OutputOffset);
}

#[test]
fn the_record_keeps_the_weights_and_reads_version_2() {
    let mut buf = [0u8; RECORD_MAX];
    let p = ControlParams::DEFAULT;
    let w = other_model();
    let rec = record::encode(&p, Some(&w), &mut buf).unwrap().to_vec();
    let d = record::decode_record(&rec).unwrap();
    assert_eq!((d.version, *d.params.get()), (3, p));
    let sec = d.observer.expect("observer section");
    assert_eq!(sec.weights, Ok(w));
    assert_eq!(sec.words_offset % 4, 0, "words aligned for use in place");
    let at = sec.words_offset;
    assert_eq!(&rec[at..at + 4], &w.input_min[0].to_le_bytes());
    // Without weights: no section, the compiled model.
    let rec0 = record::encode(&p, None, &mut buf).unwrap().to_vec();
    assert_eq!(record::decode_record(&rec0).unwrap().observer, None);
    // A version-2 record (14-byte header, parameters only), as the previous
    // firmware wrote it: read, with the compiled model.
    let mut v2 = b"CSP2".to_vec();
    v2.extend_from_slice(&rec0[4..14]);
    v2.extend_from_slice(&rec0[16..rec0.len() - 4]);
    let c = crc32(&v2);
    v2.extend_from_slice(&c.to_le_bytes());
    let d2 = record::decode_record(&v2).unwrap();
    assert_eq!((d2.version, *d2.params.get(), d2.observer), (2, p, None));
    // A section of another size: refused as such (CRC recomputed).
    let mut odd = rec.clone();
    odd[14] = odd[14].wrapping_add(1);
    let n = odd.len() - 4;
    let c = crc32(&odd[..n]);
    odd[n..].copy_from_slice(&c.to_le_bytes());
    assert_eq!(record::decode_record(&odd).unwrap_err(), RecordError::ObserverLength);
    // Weights this firmware cannot run (another structure hash): the
    // parameters still load, the section says why.
    let mut foreign = rec.clone();
    let h = at - 8;
    foreign[h] ^= 0xff;
    let n = foreign.len() - 4;
    let c = crc32(&foreign[..n]);
    foreign[n..].copy_from_slice(&c.to_le_bytes());
    let d = record::decode_record(&foreign).unwrap();
    assert_eq!(d.observer.unwrap().weights.unwrap_err().part, Part::StructureHash);
}

fn begin() -> Request {
    Request::Observer(ObserverRequest::Begin { inputs: INPUTS as u16, hidden: HIDDEN as u16, words: WORDS as u16, structure_hash: STRUCTURE_HASH })
}

fn write(start: usize, words: &[f32]) -> Request {
    Request::Observer(ObserverRequest::Write { start: start as u16, words: proto::heapless::Vec::from_slice(words).unwrap() })
}

fn send_all(srv: &mut proto::Server, d: &mut MockDrive, s: &mut MemStore, words: &[f32]) -> Option<Reply> {
    assert_eq!(ask(srv, d, s, begin()), Some(Reply::Ok));
    for (k, c) in words.chunks(block::CHUNK_WORDS).enumerate() {
        assert_eq!(ask(srv, d, s, write(k * block::CHUNK_WORDS, c)), Some(Reply::Ok));
    }
    ask(srv, d, s, Request::Observer(ObserverRequest::Commit))
}

#[test]
fn an_upload_in_chunks_is_stored_run_and_a_bad_one_changes_nothing() {
    let mut srv = server();
    let (mut d, mut s) = (MockDrive::new(), MemStore::default());
    let w = other_model();
    // Every chunk fits a frame, the largest request there is.
    let big = proto::RequestFrame { seq: u16::MAX, request: write(0, &[f32::MAX; block::CHUNK_WORDS]) };
    assert!(proto::encode(&big, &mut [0u8; proto::FRAME_MAX]).is_some());
    let r = send_all(&mut srv, &mut d, &mut s, &words4(&w));
    let Some(Reply::Observer(st)) = r else { panic!("{r:?}") };
    assert_eq!((st.source, st.words_crc), (ObserverSource::Uploaded, proto::observer::words_crc(&w)));
    assert_eq!(*d.observer, w);
    assert_eq!(record::decode_record(&s.record).unwrap().observer.unwrap().weights, Ok(w));
    let stored = s.record.clone();
    // A NaN: refused naming the part; weights and record unchanged.
    let mut bad = words4(&MODEL);
    bad[3 * INPUTS + 5] = f32::NAN;
    let r = send_all(&mut srv, &mut d, &mut s, &bad);
    assert!(matches!(r, Some(Reply::Error(Error::ObserverBlock(e))) if e.part == Part::Centres && e.index == 5), "{r:?}");
    assert_eq!((*d.observer, &s.record), (w, &stored));
    // A wrong shape or hash is refused at Begin, before any word.
    let r = ask(&mut srv, &mut d, &mut s, Request::Observer(ObserverRequest::Begin { inputs: 4, hidden: 32, words: 227, structure_hash: STRUCTURE_HASH }));
    assert!(matches!(r, Some(Reply::Error(Error::ObserverBlock(e))) if e.part == Part::Shape), "{r:?}");
    let r = ask(&mut srv, &mut d, &mut s, Request::Observer(ObserverRequest::Begin { inputs: 4, hidden: 8, words: WORDS as u16, structure_hash: [0; 8] }));
    assert!(matches!(r, Some(Reply::Error(Error::ObserverBlock(e))) if e.part == Part::StructureHash), "{r:?}");
    // Writes without Begin, a skipped chunk, a commit short of words.
    assert!(matches!(ask(&mut srv, &mut d, &mut s, write(0, &[0.0; 4])), Some(Reply::Error(Error::ObserverBlock(_)))));
    assert_eq!(ask(&mut srv, &mut d, &mut s, begin()), Some(Reply::Ok));
    let r = ask(&mut srv, &mut d, &mut s, write(block::CHUNK_WORDS, &[0.0; 4]));
    assert!(matches!(r, Some(Reply::Error(Error::ObserverBlock(e))) if e.reason == Reason::ObserverWordMissing), "{r:?}");
    assert_eq!(ask(&mut srv, &mut d, &mut s, write(0, &words4(&w)[..block::CHUNK_WORDS])), Some(Reply::Ok));
    let r = ask(&mut srv, &mut d, &mut s, Request::Observer(ObserverRequest::Commit));
    assert!(matches!(r, Some(Reply::Error(Error::ObserverBlock(e))) if e.reason == Reason::ObserverWordMissing), "{r:?}");
    assert_eq!((*d.observer, &s.record), (w, &stored));
    // Commit needs the bridge off.
    d.mode = servo_core::Mode::Running;
    let r = send_all(&mut srv, &mut d, &mut s, &words4(&MODEL));
    assert_eq!(r, Some(Reply::Error(Error::BridgeOn)));
    d.mode = servo_core::Mode::Disabled;
    // Save keeps the uploaded weights; Load brings them back.
    assert_eq!(ask(&mut srv, &mut d, &mut s, Request::Save), Some(Reply::Ok));
    d.observer = &block::COMPILED;
    let r = ask(&mut srv, &mut d, &mut s, Request::Load);
    assert!(matches!(&r, Some(Reply::Loaded { note, .. }) if note.contains("with its observer weights")), "{r:?}");
    assert_eq!(*d.observer, w);
    // Back to the compiled model, stored as such.
    let r = ask(&mut srv, &mut d, &mut s, Request::Observer(ObserverRequest::UseCompiled));
    assert!(matches!(r, Some(Reply::Observer(st)) if st.source == ObserverSource::Compiled), "{r:?}");
    assert!(std::ptr::eq(d.observer, &block::COMPILED));
    assert_eq!(record::decode_record(&s.record).unwrap().observer, None);
}

/// The drive's prediction, read back as the running model's forward pass
/// on the grid: the simulated drive runs the core's `evaluate` on the
/// weights it holds, so the model it holds is compared word for word and
/// through the forward pass.
fn predictions(m: &Weights) -> Vec<u32> {
    input_grid().iter().map(|&x| evaluate(m, x).value_m.to_bits()).collect()
}

/// Enable with compensation on, a 50 mm move: the applied shift every
/// position period, stepped deterministically (no sockets, no wall clock).
fn shifts_of_a_move(store: Option<std::path::PathBuf>) -> Vec<u32> {
    let mut o = DriveOptions::new(RigConfig::nominal().unwrap());
    o.commissioned = true;
    let uploaded = store.is_some();
    o.store = store;
    let mut d = drive::SimDrive::new(o).unwrap();
    assert_eq!(!std::ptr::eq(d.cl.controller.observer_weights(), &block::COMPILED), uploaded, "{}", d.boot_note);
    let ask = |d: &mut drive::SimDrive, request: Request| {
        let r = d.handle(&proto::RequestFrame { seq: 1, request });
        assert!(matches!(r, Some(proto::DriveFrame::Reply { reply: Reply::Command(_), .. })), "{r:?}");
    };
    ask(&mut d, Request::Command(DriveCommand::SetCompensation { enabled: true }));
    ask(&mut d, Request::Command(DriveCommand::Enable));
    let mut sink = Vec::new();
    for _ in 0..600 {
        d.step_to_boundary(&mut sink);
    }
    assert_eq!(d.cl.controller.mode(), servo_core::Mode::Running);
    ask(&mut d, Request::Command(DriveCommand::MoveTo { position_m: 0.3 }));
    (0..1500)
        .map(|_| {
            d.step_to_boundary(&mut sink);
            d.cl.controller.telemetry().position_shift_m.to_bits()
        })
        .collect()
}

#[test]
fn uploaded_weights_predict_bit_for_bit_as_compiled_ones_on_the_simulated_drive() {
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("flash.bin");
    // The same weights as the compiled model, uploaded: the drive runs an
    // uploaded copy (not the image's constant) and every prediction is the
    // compiled one's, bit for bit.
    let uploaded: &'static Weights = {
        let d = Drive::start(Some(store.clone()));
        let mut c = d.connect();
        assert_eq!(obs::status(&mut c).unwrap().source, ObserverSource::Compiled);
        let st = obs::upload(&mut c, &MODEL, ForceSource::LoadCell).unwrap();
        assert_eq!(st.words_crc, proto::observer::words_crc(&MODEL));
        // A refused upload names the part and keeps the weights.
        let mut bad = words4(&MODEL);
        bad[WORDS - 2] = f32::INFINITY;
        let e = obs::upload_words(&mut c, INPUTS as u16, HIDDEN as u16, STRUCTURE_HASH, &bad).unwrap_err().to_string();
        assert!(e.contains("output_scale") && e.contains("finite"), "{e}");
        assert_eq!(obs::status(&mut c).unwrap().words_crc, st.words_crc);
        Box::leak(Box::new(record::decode_record(&std::fs::read(&store).unwrap()).unwrap().observer.unwrap().weights.unwrap()))
    };
    assert_eq!(predictions(uploaded), predictions(&MODEL));
    // Restarted from its record, the drive runs the stored copy; with
    // compensation on, its shift is the compiled model's period by period.
    let a = shifts_of_a_move(None);
    let b = shifts_of_a_move(Some(store.clone()));
    assert!(a.iter().any(|&x| f32::from_bits(x).abs() > 1e-6), "the observer shifts the setpoint");
    assert_eq!(a, b);
    // A different block is active without reflashing.
    let d = Drive::start(Some(store.clone()));
    let mut c = d.connect();
    assert_eq!(obs::status(&mut c).unwrap().source, ObserverSource::Uploaded);
    let w = other_model();
    assert_eq!(obs::upload(&mut c, &w, ForceSource::LoadCell).unwrap().words_crc, proto::observer::words_crc(&w));
    assert_ne!(predictions(&w), predictions(&MODEL));
    assert_eq!(obs::use_compiled(&mut c).unwrap().source, ObserverSource::Compiled);
}

/// A model that uses the fifth input: the compiled one with the direction
/// of travel added (range −1 … 1, a small linear term and centres spread
/// over it), still within the shift bound.
fn five_input_model() -> Weights {
    let mut m = MODEL;
    m.input_min[4] = -1.0;
    m.input_max[4] = 1.0;
    m.input_scale[4] = 1.0;
    m.linear[4] = 0.05;
    for (k, c) in m.centres.iter_mut().enumerate() {
        c[4] = k as f32 / 4.0 - 1.0;
    }
    m
}

#[test]
fn four_and_five_input_blocks_both_validate_and_the_fifth_input_is_unheard_by_a_four_input_model() {
    use servo_core::observer::{model, NETWORK_INPUTS};
    // The compiled four-input model in the five slots predicts bit for bit
    // as on its own, whatever the fifth input says.
    for x in input_grid() {
        let own = evaluate(&model::MODEL, [x[0], x[1], x[2], x[3]]);
        let lifted = evaluate(&MODEL, x);
        assert_eq!((lifted.value_m.to_bits(), lifted.clamped, lifted.valid), (own.value_m.to_bits(), own.clamped, own.valid), "{x:?}");
    }
    assert_eq!(block::inputs_of(&MODEL), 4);
    // A five-input block: 87 words, its own hash; it hears the fifth input.
    let m5 = five_input_model();
    assert_eq!(block::inputs_of(&m5), NETWORK_INPUTS);
    let (w5, n5) = block::to_block_words(&m5, NETWORK_INPUTS);
    assert_eq!(n5, block::WORDS);
    let h5 = block::structure_hash_for(NETWORK_INPUTS, ForceSource::LoadCell);
    assert_ne!(h5, STRUCTURE_HASH);
    let back = block::validate(NETWORK_INPUTS as u16, HIDDEN as u16, &h5, &w5[..n5], SHIFT_MAX_M, ForceSource::LoadCell).unwrap();
    assert_eq!(back, m5);
    let x = [0.0, 0.0, 0.2, 1000.0];
    let (up, down) = (evaluate(&m5, [x[0], x[1], x[2], x[3], 1.0]), evaluate(&m5, [x[0], x[1], x[2], x[3], -1.0]));
    assert_ne!(up.value_m, down.value_m, "the fifth input changes a five-input model's prediction");
    // Shape and hash follow the input count: refused, named.
    let e = block::validate(NETWORK_INPUTS as u16, HIDDEN as u16, &STRUCTURE_HASH, &w5[..n5], SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!(e.part, Part::StructureHash);
    let e = block::validate(NETWORK_INPUTS as u16, HIDDEN as u16, &h5, &words4(&MODEL), SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!((e.part, e.reason), (Part::Shape, Reason::ObserverWordCount));
    let e = block::validate(6, HIDDEN as u16, &h5, &w5[..n5], SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!((e.part, e.reason), (Part::Shape, Reason::ObserverInputCount));
    // An empty range of the fifth input is refused as any other.
    let mut bad = m5;
    bad.input_max[4] = bad.input_min[4];
    let (wb, nb) = block::to_block_words(&bad, NETWORK_INPUTS);
    let e = block::validate(NETWORK_INPUTS as u16, HIDDEN as u16, &h5, &wb[..nb], SHIFT_MAX_M, ForceSource::LoadCell).unwrap_err();
    assert_eq!((e.part, e.index), (Part::InputMax, 4));
    // Both kinds go through the flash record and come back as they were.
    let mut buf = [0u8; RECORD_MAX];
    for w in [other_model(), m5] {
        let rec = record::encode(&ControlParams::DEFAULT, Some(&w), &mut buf).unwrap().to_vec();
        assert_eq!(record::decode_record(&rec).unwrap().observer.unwrap().weights, Ok(w));
    }
}

#[test]
fn a_five_input_model_uploads_and_the_drive_reports_its_shape() {
    let dir = tempfile::tempdir().unwrap();
    let d = Drive::start(Some(dir.path().join("flash.bin")));
    let mut c = d.connect();
    let m5 = five_input_model();
    let st = obs::upload(&mut c, &m5, ForceSource::LoadCell).unwrap();
    assert_eq!((st.inputs, st.words), (5, block::WORDS as u16));
    assert_eq!(st.words_crc, proto::observer::words_crc(&m5));
    assert_eq!(st.structure_hash, block::structure_hash_for(5, ForceSource::LoadCell));
    let st = obs::upload(&mut c, &MODEL, ForceSource::LoadCell).unwrap();
    assert_eq!((st.inputs, st.words, st.structure_hash), (4, WORDS as u16, STRUCTURE_HASH));
}
