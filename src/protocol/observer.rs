//! The observer weight block on the drive's side of the protocol: status,
//! upload (`Begin`, `Write`…, `Commit`), back to the compiled model, and
//! the weights that go with a saved or loaded record.
//!
//! Weights run only from where the store keeps them (`ParamStore::
//! stored_observer`: in place in flash on the board), so an uploaded block
//! costs the controller a reference, not a second copy in RAM; that is why
//! `Commit` stores the block with the present parameters, as `Save` does,
//! and why it needs the bridge off (a flash erase stalls the PWM
//! interrupt). A refused block leaves the running weights and the stored
//! record as they were.

use super::drive::{DriveAccess, ParamStore};
use super::messages::*;
use super::server::text;
use crate::controller::Command;
use crate::observer::block::{self, Weights};
use crate::observer::model;
use crate::params::{record, ControlParams};
use crate::telemetry::Mode;
use crc::{Crc, NoTable, CRC_32_ISO_HDLC};

const CRC: Crc<u32, NoTable> = Crc::<u32, NoTable>::new(&CRC_32_ISO_HDLC);

/// CRC-32 of a model's block words (`f32` little-endian, block order), as
/// the block of its own input count: what the host uploaded.
pub fn words_crc(m: &Weights) -> u32 {
    let mut d = CRC.digest();
    let (words, n) = block::to_block_words(m, block::inputs_of(m));
    for w in words.iter().take(n) {
        d.update(&w.to_le_bytes());
    }
    d.finalize()
}

/// Whether `m` is the compiled model (by address: an uploaded copy of the
/// same words still counts as uploaded).
pub fn is_compiled(m: &Weights) -> bool {
    core::ptr::eq(m, &block::COMPILED)
}

/// The force input the drive's parameters select: uploaded weights must
/// have been trained on it.
pub fn force_source(p: &ControlParams) -> block::ForceSource {
    block::ForceSource::selected(p.compensation.force_from_estimate)
}

/// The status reply for the weights `m` on a drive whose force input is
/// `source`: their input count, word count and CRC, and the structure hash
/// of a block of that input count on that force input.
pub fn status(m: &Weights, source: block::ForceSource) -> ObserverStatus {
    let inputs = block::inputs_of(m);
    ObserverStatus {
        source: if is_compiled(m) { ObserverSource::Compiled } else { ObserverSource::Uploaded },
        inputs: inputs as u16,
        hidden: model::HIDDEN as u16,
        words: block::words_for(inputs) as u16,
        structure_hash: block::structure_hash_for(inputs, source),
        words_crc: words_crc(m),
    }
}

fn bridge_off<D: DriveAccess>(drive: &D) -> bool {
    matches!(drive.status().telemetry.mode, Mode::Disabled | Mode::Fault)
}

fn no_staging() -> Error {
    Error::ObserverStore { reason: text("this drive's store takes no observer weights") }
}

/// One `Request::Observer`.
pub(super) fn handle<D: DriveAccess, S: ParamStore>(o: &ObserverRequest, drive: &mut D, store: &mut S) -> Result<Reply, Error> {
    match o {
        ObserverRequest::Status => Ok(Reply::Observer(status(drive.observer_weights(), force_source(&drive.params())))),
        ObserverRequest::Begin { inputs, hidden, words, structure_hash } => {
            let source = force_source(&drive.params());
            let st = store.observer_staging().ok_or_else(no_staging)?;
            st.begin(*inputs, *hidden, *words, *structure_hash, source).map_err(Error::ObserverBlock)?;
            Ok(Reply::Ok)
        }
        ObserverRequest::Write { start, words } => {
            let st = store.observer_staging().ok_or_else(no_staging)?;
            st.write(*start, words).map_err(Error::ObserverBlock)?;
            Ok(Reply::Ok)
        }
        ObserverRequest::Commit => {
            if !bridge_off(drive) {
                return Err(Error::BridgeOn);
            }
            let p = drive.params();
            let st = store.observer_staging().ok_or_else(no_staging)?;
            let w = st.commit(p.faults.observer_shift_max_m, force_source(&p)).map_err(Error::ObserverBlock)?;
            store_record(&p, Some(&w), drive, store)?;
            Ok(Reply::Observer(status(drive.observer_weights(), force_source(&p))))
        }
        ObserverRequest::UseCompiled => {
            if !bridge_off(drive) {
                return Err(Error::BridgeOn);
            }
            let p = drive.params();
            store_record(&p, None, drive, store)?;
            Ok(Reply::Observer(status(drive.observer_weights(), force_source(&p))))
        }
    }
}

/// Stores `p` with `weights` (`None`: the compiled model) as the record,
/// then runs the weights from where the store keeps them. The store's
/// copy must read back bit for bit.
pub(super) fn store_record<D: DriveAccess, S: ParamStore>(
    p: &ControlParams,
    weights: Option<&Weights>,
    drive: &mut D,
    store: &mut S,
) -> Result<(), Error> {
    let mut buf = [0u8; record::RECORD_MAX];
    let bytes = record::encode(p, weights, &mut buf).map_err(|e| Error::Storage { reason: text(e.reason()) })?;
    store.save(bytes).map_err(|reason| Error::Storage { reason })?;
    let run: &'static Weights = match weights {
        None => &block::COMPILED,
        Some(w) => {
            let kept = store
                .stored_observer()
                .map_err(|reason| Error::ObserverStore { reason })?
                .ok_or_else(|| Error::ObserverStore { reason: text("the store did not give back the weights it saved") })?;
            let same = block::to_words(kept).iter().zip(block::to_words(w).iter()).all(|(a, b)| a.to_bits() == b.to_bits());
            if !same {
                return Err(Error::ObserverStore { reason: text("the stored weights read back differently") });
            }
            kept
        }
    };
    drive.command(Command::SetObserverWeights { weights: run }).map_err(Error::Command)?;
    Ok(())
}

/// After a record was loaded: runs its weights (or the compiled model) and
/// says which, for the `Loaded` note.
pub(super) fn run_stored<D: DriveAccess, S: ParamStore>(
    section: Option<record::ObserverSection>,
    drive: &mut D,
    store: &mut S,
) -> Text {
    let (run, note): (&'static Weights, Text) = match section.map(|s| s.weights) {
        None => (&block::COMPILED, text("record applied; compiled observer weights")),
        Some(Ok(_)) => match store.stored_observer() {
            Ok(Some(w)) => (w, text("record applied with its observer weights")),
            _ => (&block::COMPILED, text("record applied; its observer weights could not be read: compiled weights run")),
        },
        Some(Err(e)) => {
            let mut t = text("record applied; its observer weights are refused (");
            let _ = t.push_str(e.part.name());
            let _ = t.push_str("): compiled weights run");
            (&block::COMPILED, t)
        }
    };
    if drive.command(Command::SetObserverWeights { weights: run }).is_err() {
        return text("record applied; observer weights not switched");
    }
    note
}
