//! Reading a family back, and the family modes' common report: a row per
//! rig, the worst case of every figure, in `summary.json` and `family.md`.

use crate::config::RigConfig;
use anyhow::{bail, Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One rig of a family on disk.
#[derive(Clone, Debug)]
pub struct FamilyRig {
    pub name: String,
    pub path: PathBuf,
    pub rig: RigConfig,
}

/// The rigs of `dir`: those `family.json` lists (as `host-sim rigs`
/// writes it), else every `*.toml` in name order, any other file refused. Every file must load;
/// the first that does not is named with its field.
pub fn load_family(dir: &Path) -> Result<Vec<FamilyRig>> {
    if !dir.is_dir() {
        bail!("--family {}: not a folder (write one with `host-sim rigs --out DIR`)", dir.display());
    }
    let manifest = dir.join("family.json");
    let files: Vec<(String, PathBuf)> = if manifest.exists() {
        let text = std::fs::read_to_string(&manifest).with_context(|| format!("reading {}", manifest.display()))?;
        let v: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", manifest.display()))?;
        let Some(rigs) = v.get("rigs").and_then(|r| r.as_array()) else {
            bail!("{}: no `rigs` list", manifest.display());
        };
        let mut out = vec![];
        for (i, r) in rigs.iter().enumerate() {
            let (Some(name), Some(file)) = (r.get("name").and_then(|x| x.as_str()), r.get("file").and_then(|x| x.as_str()))
            else {
                bail!("{}: rigs[{i}] needs `name` and `file`", manifest.display());
            };
            out.push((name.to_string(), dir.join(file)));
        }
        out
    } else {
        let mut out = vec![];
        for e in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
            let p = e?.path();
            if p.extension().is_some_and(|x| x == "toml") {
                let name = p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
                out.push((name, p));
            } else {
                // Without a manifest every file is meant as a rig: one that
                // is not (a backup, a note) is named, never passed over.
                bail!(
                    "--family {}: {} is not a rig file (*.toml); move it out, or list the rigs in {}/family.json",
                    dir.display(),
                    p.display(),
                    dir.display()
                );
            }
        }
        out.sort();
        out
    };
    if files.is_empty() {
        bail!("--family {}: no rig files", dir.display());
    }
    files
        .into_iter()
        .map(|(name, path)| Ok(FamilyRig { rig: RigConfig::load(&path)?, name, path }))
        .collect()
}

/// One rig's result in a family mode.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RigRow {
    pub rig: String,
    pub passed: bool,
    /// The suite's verdict in words ("ok", or what failed).
    pub verdict: String,
    /// Figures by name; `None` where the rig gave none.
    pub figures: Vec<(String, Option<f64>)>,
}

/// How a figure's worst case is taken.
#[derive(Clone, Copy, Debug)]
pub enum Worst {
    Max,
    Min,
}

/// `summary.json` and `family.md` for a family mode: every row, and for
/// each figure in `worst` its worst value over the family and the rig.
pub fn write_family_report(
    command: &str,
    family: &Path,
    rows: &[RigRow],
    worst: &[(&str, Worst)],
    extra: serde_json::Value,
    wall_s: f64,
    out: &Path,
) -> Result<serde_json::Value> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut worst_json = serde_json::Map::new();
    for (fig, how) in worst {
        let mut best: Option<(f64, &str)> = None;
        for r in rows {
            let Some(v) = r.figures.iter().find(|(n, _)| n == fig).and_then(|(_, v)| *v) else { continue };
            let better = match (best, how) {
                (None, _) => true,
                (Some((b, _)), Worst::Max) => v > b,
                (Some((b, _)), Worst::Min) => v < b,
            };
            if better {
                best = Some((v, &r.rig));
            }
        }
        worst_json.insert(
            (*fig).to_string(),
            match best {
                Some((v, rig)) => serde_json::json!({ "value": v, "rig": rig }),
                None => serde_json::Value::Null,
            },
        );
    }
    let per_rig: Vec<serde_json::Value> = rows
        .iter()
        .map(|r| {
            let mut m = serde_json::Map::new();
            m.insert("rig".into(), r.rig.clone().into());
            m.insert("passed".into(), r.passed.into());
            m.insert("verdict".into(), r.verdict.clone().into());
            for (n, v) in &r.figures {
                m.insert(n.clone(), v.map_or(serde_json::Value::Null, Into::into));
            }
            serde_json::Value::Object(m)
        })
        .collect();
    let summary = serde_json::json!({
        "command": command,
        "family": family.display().to_string(),
        "rigs": rows.len(),
        "rigs_passed": rows.iter().filter(|r| r.passed).count(),
        "rigs_failed": rows.iter().filter(|r| !r.passed).map(|r| r.rig.clone()).collect::<Vec<_>>(),
        "worst": worst_json,
        "per_rig": per_rig,
        "suite": extra,
        "wall_s": wall_s,
    });
    let path = out.join("summary.json");
    std::fs::write(&path, serde_json::to_string_pretty(&summary)?).with_context(|| format!("writing {}", path.display()))?;
    std::fs::write(out.join("family.md"), markdown(rows)).with_context(|| format!("writing {}/family.md", out.display()))?;
    Ok(summary)
}

/// The per-rig table.
pub fn markdown(rows: &[RigRow]) -> String {
    let names: Vec<&str> = rows.first().map(|r| r.figures.iter().map(|(n, _)| n.as_str()).collect()).unwrap_or_default();
    let mut md = format!("| rig | passed | {} | verdict |\n|---|---|{}---|\n", names.join(" | "), "---|".repeat(names.len()));
    for r in rows {
        let figs: Vec<String> =
            r.figures.iter().map(|(_, v)| v.map_or("–".to_string(), |v| format!("{v:.4}"))).collect();
        let _ = writeln!(md, "| {} | {} | {} | {} |", r.rig, if r.passed { "yes" } else { "**no**" }, figs.join(" | "), r.verdict);
    }
    md
}
