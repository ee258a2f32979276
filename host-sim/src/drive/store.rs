//! The simulated drive's parameter store: one file standing in for the
//! board's flash. It holds the core's record (`servo_core::params::record`:
//! magic, parameter-schema hash, one word per leaf, CRC-32) byte for byte, so a
//! record from another layout or a corrupted one is refused as the board
//! refuses it.

use servo_core::protocol::drive::ParamStore;
use servo_core::protocol::server::text;
use servo_core::protocol::Text;
use std::path::PathBuf;

#[derive(Clone, Debug)]
pub struct FileStore {
    pub path: Option<PathBuf>,
}

impl FileStore {
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
}
