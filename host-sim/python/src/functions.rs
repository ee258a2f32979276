//! The module-level functions of `servo_drive._native`: the schema's
//! words (parameter paths, signal names, hashes, defaults), the paper run's
//! reference, a test frame, and the host tool's analysis (step figures,
//! frequency response).

use super::*;

/// Every parameter path with its type: JSON list of {path, kind}.
#[pyfunction]
pub(crate) fn param_paths() -> String {
    json_text(&serde_json::Value::Array(
        (0..protocol::params::PARAM_COUNT)
            .filter_map(protocol::params::name)
            .map(|(p, k)| serde_json::json!({ "path": p.as_str(), "kind": kind_name(k) }))
            .collect(),
    ))
}

/// The capture signals and telemetry fields, by name.
#[pyfunction]
pub(crate) fn signal_names() -> (Vec<String>, Vec<String>) {
    (tool::SIGNAL_NAMES.iter().map(|(n, _)| n.to_string()).collect(), view::TELEMETRY_NAMES.iter().map(|n| n.to_string()).collect())
}

/// This package's schema hashes (hex): (messages, parameters).
#[pyfunction]
pub(crate) fn schema_hashes() -> (String, String) {
    (client::hex(&SCHEMA_HASH), client::hex(&PARAMS_SCHEMA_HASH))
}

/// Every parameter's default value and, where the core's own validation
/// bounds the leaf by itself, its lower bound: found by asking
/// `ControlParams::validate` about 0 and a negative value on the defaults
/// (`min` with `min_exclusive`). Bounds between fields (stroke min < max, …)
/// are the drive's to report at `param set`. JSON list of {path, kind,
/// value, min, min_exclusive, max_abs}.
#[pyfunction]
pub(crate) fn defaults() -> String {
    let p = ControlParams::default();
    let rejects = |path: &str, index: usize, v: protocol::Value| {
        let mut q = p;
        protocol::params::set(&mut q, path, v).is_ok() && matches!(q.validate(), Err(e) if usize::from(e.leaf) == index)
    };
    json_text(&serde_json::Value::Array(
        (0..protocol::params::PARAM_COUNT)
            .filter_map(|i| protocol::params::name(i).map(|(p, k)| (i, p, k)))
            .map(|(i, path, kind)| {
                let path = path.as_str();
                let v = protocol::params::get(&p, path).ok();
                let (min, exclusive) = match kind {
                    protocol::ValueKind::F32 if rejects(path, i, protocol::Value::F32(0.0)) => (Some(0.0), true),
                    protocol::ValueKind::F32 if rejects(path, i, protocol::Value::F32(-1e-6)) => (Some(0.0), false),
                    protocol::ValueKind::U32 if rejects(path, i, protocol::Value::U32(0)) => (Some(1.0), false),
                    _ => (None, false),
                };
                // The core's physical range: the largest size the leaf may have
                // (by its unit, from the default set's ratings).
                let max_abs = servo_core::params::ranges::leaf_bound(i, &p).filter(|b| b.is_finite() && *b > 0.0);
                serde_json::json!({ "path": path, "kind": kind_name(kind), "value": v.map(|v| value_json(path, &v)), "min": min, "min_exclusive": exclusive, "max_abs": max_abs })
            })
            .collect(),
    ))
}

/// The paper cycle's motor-side reference at the position-loop rate (the
/// one `host-sim drive bench-stream` streams): (t_s, position_m, velocity_m_s).
#[pyfunction]
#[pyo3(signature = (rig = None))]
pub(crate) fn paper_reference(rig: Option<std::path::PathBuf>) -> PyResult<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let rig = RigConfig::load_or_nominal(rig.as_ref()).map_err(|e| raise("DriveError", format!("{e:#}"), serde_json::json!({})))?;
    let rows = host_sim::tool::bench::paper_reference(&rig).map_err(|e| raise("DriveError", format!("{e:#}"), serde_json::json!({})))?;
    Ok((rows.iter().map(|r| r.t_s).collect(), rows.iter().map(|r| r.position_m).collect(), rows.iter().map(|r| r.velocity_m_s).collect()))
}

/// One encoded `Info` reply (seq `seq`) with the given hashes: what a drive
/// of another schema sends, for tests of the connect check.
#[pyfunction]
pub(crate) fn encode_info_reply(seq: u16, schema_hash: [u8; 8], params_schema_hash: [u8; 8]) -> PyResult<Vec<u8>> {
    let text = |s: &str| protocol::Text::try_from(s).map_err(|_| anyhow!("text too long"));
    let mk = || -> anyhow::Result<Vec<u8>> {
        let info = Info {
            firmware_version: text("0.0.0-other")?,
            git_hash: text("0000000")?,
            schema_hash,
            params_schema_hash,
            board: text("other-build")?,
            mode: servo_core::Mode::Disabled,
            faults: 0,
            pwm_frequency_hz: 20_000.0,
            boot_record: protocol::BootRecord::Unknown,
            stream_period_s: 0.0,
            protocol_version: protocol::PROTOCOL_VERSION,
        };
        let mut buf = [0u8; protocol::FRAME_MAX];
        let frame = DriveFrame::Reply { seq, reply: Reply::Info(info) };
        Ok(protocol::encode(&frame, &mut buf).ok_or_else(|| anyhow!("frame too large"))?.to_vec())
    };
    mk().map_err(|e| raise("DriveError", format!("{e:#}"), serde_json::json!({})))
}

/// Step figures of `y` (sampled at `dt` from t = 0; step at `t0`), the host
/// tool's: JSON {amplitude, initial, final_value, rise_time_s,
/// overshoot_pct, settling_time_s}.
#[pyfunction]
pub(crate) fn step_figures(y: Vec<f64>, dt: f64, t0: f64, amplitude: f64) -> String {
    json_text(&serde_json::to_value(host_sim::tool::analysis::step_figures(&y, dt, t0, amplitude)).unwrap_or_default())
}

/// H1 frequency response y/x (Welch, Hann, 50 % overlap, `nfft` a power of
/// two), the host tool's: (freq_hz, gain_db, phase_deg, coherence).
#[pyfunction]
pub(crate) fn frf_h1(x: Vec<f64>, y: Vec<f64>, dt: f64, nfft: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let f = host_sim::tool::analysis::h1(&x, &y, dt, nfft);
    (f.freq_hz, f.gain_db, f.phase_deg, f.coherence)
}

