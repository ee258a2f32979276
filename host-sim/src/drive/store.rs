//! The simulated drive's parameter store: one file standing in for the
//! board's flash. It holds the core's record (`servo_core::params::record`:
//! magic, parameter-schema hash, one word per leaf, CRC-32) byte for byte, so a
//! record from another layout or a corrupted one is refused as the board
//! refuses it.
//!
//! Like the board it gathers an uploaded observer block beside the record
//! and gives back the weights of the record it holds, read from the file
//! (the board runs them in place from flash; here a leaked copy per save,
//! a few hundred bytes).

use servo_core::observer::block::{Staging, Weights};
use servo_core::params::record;
use servo_core::protocol::drive::ParamStore;
use servo_core::protocol::server::text;
use servo_core::protocol::Text;
use std::path::PathBuf;

#[derive(Clone, Debug)]
pub struct FileStore {
    pub path: Option<PathBuf>,
    staging: Box<Staging>,
}

impl FileStore {
    pub fn new(path: Option<PathBuf>) -> Self {
        Self { path, staging: Box::new(Staging::new()) }
    }

    /// The stored bytes; `Ok(None)` when nothing is stored.
    pub fn read(&self) -> Result<Option<Vec<u8>>, String> {
        let Some(path) = &self.path else { return Ok(None) };
        match std::fs::read(path) {
            Ok(b) => Ok(Some(b)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(format!("{}: {e}", path.display())),
        }
    }
}

impl ParamStore for FileStore {
    fn save(&mut self, record: &[u8]) -> Result<(), Text> {
        let Some(path) = &self.path else { return Err(text("no --store file given to the simulated drive")) };
        // Written whole or not at all: a temporary file renamed over the old.
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, record).map_err(|e| text(&format!("{}: {e}", tmp.display())))?;
        std::fs::rename(&tmp, path).map_err(|e| text(&format!("{}: {e}", path.display())))
    }

    fn load(&mut self, buf: &mut [u8]) -> Result<usize, Text> {
        match self.read() {
            Ok(None) => Ok(0),
            Ok(Some(b)) if b.len() > buf.len() => Err(text("stored record longer than the record buffer")),
            Ok(Some(b)) => {
                buf[..b.len()].copy_from_slice(&b);
                Ok(b.len())
            }
            Err(e) => Err(text(&e)),
        }
    }

    fn observer_staging(&mut self) -> Option<&mut Staging> {
        self.path.is_some().then_some(&mut *self.staging)
    }

    fn stored_observer(&mut self) -> Result<Option<&'static Weights>, Text> {
        let Some(bytes) = self.read().map_err(|e| text(&e))? else { return Ok(None) };
        let d = record::decode_record(&bytes).map_err(|e| text(e.reason()))?;
        match d.observer.map(|s| s.weights) {
            None => Ok(None),
            Some(Ok(w)) => Ok(Some(Box::leak(Box::new(w)))),
            Some(Err(e)) => Err(text(&format!("stored observer block refused: {} ({})", e.part.name(), e.reason.text()))),
        }
    }
}
