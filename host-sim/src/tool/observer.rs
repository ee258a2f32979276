//! The observer's weights on a drive: which run, upload the trainer's
//! `model.json` as a weight block (`servo_core::observer::block`), back to
//! the compiled model.
//!
//! The upload is `Begin` (shape and structure hash, refused before any word
//! is sent), `Write` in chunks of `CHUNK_WORDS`, `Commit` (the drive checks
//! the whole block, stores it in flash with the present parameters and runs
//! it). The drive answers with the CRC of the words it runs, which must be
//! the file's: the upload is verified, not assumed.

use super::client::{describe, Client};
use crate::trainer::codegen::to_core_model;
use crate::trainer::dataset::ModelKind;
use crate::trainer::network::TrainedModel;
use anyhow::{anyhow, bail, Context, Result};
use servo_core::observer::block::{self, ForceSource, Weights, CHUNK_WORDS, WORDS};
use servo_core::observer::model::HIDDEN;
use servo_core::protocol::observer::words_crc;
use servo_core::protocol::{ObserverRequest, ObserverSource, ObserverStatus, Reply, Request};
use std::path::Path;

/// The firmware's model of a trainer's `model.json` (the same `f32`
/// rounding as the code generator's, so the words are those a compiled
/// model would hold).
pub fn read_model(path: &Path) -> Result<Weights> {
    read_model_file(path).map(|(w, _)| w)
}

/// [`read_model`] and the force the model was trained on, which the upload
/// names to the drive (through the structure hash).
pub fn read_model_file(path: &Path) -> Result<(Weights, ForceSource)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let m: TrainedModel = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a trainer model.json (written by `host-sim train --out DIR`)", path.display()))?;
    if m.kind != ModelKind::Error {
        bail!("{}: a {:?} model; the drive's observer predicts the terminal error (train with --kind error)", path.display(), m.kind);
    }
    if m.hidden() != HIDDEN {
        bail!(
            "{}: shape: {} hidden units; this firmware's network has {HIDDEN} (train with --hidden {HIDDEN})",
            path.display(),
            m.hidden()
        );
    }
    let Some(source) = m.force_source else {
        bail!(
            "{}: no \"force_source\" (\"load_cell\" or \"estimate\"): the file predates the trainer recording which force it was trained on; train it again",
            path.display()
        );
    };
    Ok((to_core_model::<HIDDEN>(&m).with_context(|| format!("{}", path.display()))?, source))
}

fn status_of(r: Reply) -> Result<ObserverStatus> {
    match r {
        Reply::Observer(s) => Ok(s),
        r => bail!("unexpected reply {r:?}"),
    }
}

/// Which weights the drive runs.
pub fn status(c: &mut Client) -> Result<ObserverStatus> {
    status_of(c.ask(Request::Observer(ObserverRequest::Status))?)
}

/// Sends a block as given (shape, hash and words unchecked here: the drive
/// checks them); the drive's status after `Commit`. A refusal is an error
/// naming the part.
pub fn upload_words(c: &mut Client, inputs: u16, hidden: u16, structure_hash: [u8; 8], words: &[f32]) -> Result<ObserverStatus> {
    let refused = |e: servo_core::protocol::Error| anyhow!("{}", describe(&e));
    let n = u16::try_from(words.len()).map_err(|_| anyhow!("{} words: too many", words.len()))?;
    match c.request(Request::Observer(ObserverRequest::Begin { inputs, hidden, words: n, structure_hash }))? {
        Reply::Ok => {}
        Reply::Error(e) => return Err(refused(e)),
        r => bail!("Begin answered {r:?}"),
    }
    for (k, chunk) in words.chunks(CHUNK_WORDS).enumerate() {
        let start = (k * CHUNK_WORDS) as u16;
        let v = servo_core::protocol::heapless::Vec::from_slice(chunk).map_err(|_| anyhow!("chunk too long"))?;
        match c.request(Request::Observer(ObserverRequest::Write { start, words: v }))? {
            Reply::Ok => {}
            Reply::Error(e) => return Err(refused(e)),
            r => bail!("Write answered {r:?}"),
        }
    }
    match c.request(Request::Observer(ObserverRequest::Commit))? {
        Reply::Error(e) => Err(refused(e)),
        r => status_of(r),
    }
}

/// Uploads `w`, trained on the force `source`, and checks that the drive
/// runs exactly these words. A drive whose force input is the other one
/// refuses it, naming both.
pub fn upload(c: &mut Client, w: &Weights, source: ForceSource) -> Result<ObserverStatus> {
    // As a block of the model's own input count (four: the paper's map;
    // five: with the direction of travel).
    let inputs = block::inputs_of(w);
    let (words, n) = block::to_block_words(w, inputs);
    let s = upload_words(c, inputs as u16, HIDDEN as u16, block::structure_hash_for(inputs, source), &words[..n])?;
    let want = words_crc(w);
    if s.source != ObserverSource::Uploaded || s.words_crc != want {
        bail!(
            "verify: the drive runs {:?} weights with CRC {:08x}, the file's words have {want:08x}",
            s.source,
            s.words_crc
        );
    }
    Ok(s)
}

/// Back to the compiled model (stored as such).
pub fn use_compiled(c: &mut Client) -> Result<ObserverStatus> {
    status_of(c.ask(Request::Observer(ObserverRequest::UseCompiled))?)
}

/// One line for a status.
pub fn describe_status(s: &ObserverStatus) -> String {
    format!(
        "observer weights: {} ({} inputs, {} hidden, {} words, structure {}, words CRC {:08x})",
        match s.source {
            ObserverSource::Compiled => "compiled into the image",
            ObserverSource::Uploaded => "uploaded, stored in flash",
        },
        s.inputs,
        s.hidden,
        s.words,
        super::client::hex(&s.structure_hash),
        s.words_crc
    )
}

/// `WORDS`, for callers building blocks by hand (tests, other tools).
pub const BLOCK_WORDS: usize = WORDS;
