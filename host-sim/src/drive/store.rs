//! The simulated drive's parameter store: one file standing in for the
//! board's flash record. The record is the postcard bytes of
//! `ControlParams` after the 8-byte `PARAMS_SCHEMA_HASH`, so a record from
//! another layout is refused as the board refuses it.

use servo_core::protocol::PARAMS_SCHEMA_HASH;
use servo_core::ControlParams;
use std::path::PathBuf;

#[derive(Clone, Debug)]
pub struct FileStore {
    pub path: Option<PathBuf>,
}

impl FileStore {
    pub fn save(&self, p: &ControlParams) -> Result<(), String> {
        let Some(path) = &self.path else { return Err("no --store file".into()) };
        let mut bytes = PARAMS_SCHEMA_HASH.to_vec();
        bytes.extend(postcard::to_allocvec(p).map_err(|e| e.to_string())?);
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, &bytes).map_err(|e| format!("{}: {e}", tmp.display()))?;
        std::fs::rename(&tmp, path).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// `Ok(None)`: no record yet.
    pub fn load(&self) -> Result<Option<ControlParams>, String> {
        let Some(path) = &self.path else { return Err("no --store file".into()) };
        let bytes = match std::fs::read(path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(format!("{}: {e}", path.display())),
        };
        let Some(body) = bytes.strip_prefix(&PARAMS_SCHEMA_HASH[..]) else {
            return Err("record of another parameter layout".into());
        };
        let p: ControlParams = postcard::from_bytes(body).map_err(|e| format!("unreadable record: {e}"))?;
        p.validate().map_err(|e| format!("saved set invalid: {e}"))?;
        Ok(Some(p))
    }
}
