//! Rig families: rigs a second unit of the same cylinder could be, drawn
//! from a base rig file within stated tolerances (`spec`), written as rig
//! files that keep the base's comments and say what was drawn, and read
//! back for the suites' family modes (`family`).

pub mod family;
pub mod spec;

pub use family::{load_family, FamilyRig};
pub use spec::{Draw, FamilySpec, SpecError, C7_LEAD_ERROR_M_PER_M};

use crate::config::RigConfig;
use anyhow::{anyhow, bail, Context, Result};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::fmt::Write as _;
use std::path::Path;

/// Most rigs one request may draw.
pub const MAX_COUNT: usize = 10_000;

/// One rig of a family before it is written: its name and draw.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Member {
    pub name: String,
    pub kind: &'static str,
    pub draw: Draw,
}

/// `count` drawn rigs from `seed`, then the five corners if asked.
pub fn members(spec: &FamilySpec, count: usize, seed: u64, corners: bool) -> Vec<Member> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out: Vec<Member> = (0..count)
        .map(|k| Member { name: format!("rig_{:03}", k + 1), kind: "drawn", draw: Draw::random(spec, &mut rng) })
        .collect();
    if corners {
        out.extend(Draw::corners(spec).into_iter().map(|(name, draw)| Member { name: name.into(), kind: "corner", draw }));
    }
    out
}

/// Writes the family into `out`: one rig file per member (the base file's
/// text and comments, each drawn value replaced and annotated) and
/// `family.json` (the request and every draw). Each file is read back
/// and validated before the next is written.
pub fn write_family(
    base_text: &str,
    base_origin: &str,
    spec: &FamilySpec,
    count: usize,
    seed: u64,
    corners: bool,
    out: &Path,
) -> Result<Vec<Member>> {
    if count == 0 && !corners {
        bail!("--count: 0 rigs and --no-corners leave an empty family; ask for at least 1");
    }
    if count > MAX_COUNT {
        bail!("--count: {count} is more than {MAX_COUNT} rigs");
    }
    let base = RigConfig::from_toml(base_text, base_origin)?;
    spec.check(&base).map_err(|e| anyhow!("{e}"))?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let list = members(spec, count, seed, corners);
    for m in &list {
        let rig = m.draw.apply(&base);
        let text = rig_file_text(base_text, &base, &rig, m, spec, seed, base_origin)?;
        let path = out.join(format!("{}.toml", m.name));
        // The file as written must load: the generator never hands a user
        // a rig the loader refuses.
        RigConfig::from_toml(&text, &path.display().to_string())
            .with_context(|| format!("{} (drawn {:?}) does not load: a generator fault", m.name, m.draw))?;
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    }
    let manifest = serde_json::json!({
        "command": "rigs",
        "base": base_origin,
        "seed": seed,
        "count": count,
        "corners": corners,
        "tolerances": spec,
        "rigs": list.iter().map(|m| serde_json::json!({
            "name": m.name,
            "file": format!("{}.toml", m.name),
            "kind": m.kind,
            "draw": m.draw,
        })).collect::<Vec<_>>(),
    });
    let path = out.join("family.json");
    std::fs::write(&path, serde_json::to_string_pretty(&manifest)?).with_context(|| format!("writing {}", path.display()))?;
    Ok(list)
}

/// The base file's text with every `[plant]` value the draw changed
/// replaced and annotated, under a header that says what the rig is.
fn rig_file_text(
    base_text: &str,
    base: &RigConfig,
    rig: &RigConfig,
    m: &Member,
    spec: &FamilySpec,
    seed: u64,
    origin: &str,
) -> Result<String> {
    let mut doc: toml_edit::DocumentMut = base_text.parse().with_context(|| format!("{origin}: not valid TOML"))?;
    let old = toml::Value::try_from(&base.plant)?;
    let new = toml::Value::try_from(&rig.plant)?;
    let plant = doc.entry("plant").or_insert(toml_edit::table());
    let plant = plant.as_table_like_mut().ok_or_else(|| anyhow!("{origin}: `plant` is not a table"))?;
    set_changed(plant, &old, &new, "plant")?;
    let old = toml::Value::try_from(base.control)?;
    let new = toml::Value::try_from(rig.control)?;
    let control = doc.entry("control").or_insert(toml_edit::table());
    let control = control.as_table_like_mut().ok_or_else(|| anyhow!("{origin}: `control` is not a table"))?;
    set_changed(control, &old, &new, "control")?;
    let d = &m.draw;
    let mut h = String::new();
    let _ = writeln!(h, "# Rig `{}` of a family drawn by `host-sim rigs --seed {seed}` from {origin}.", m.name);
    let _ = writeln!(h, "# A second unit of the same cylinder: [plant] differs from the base as");
    let _ = writeln!(h, "# below (each changed value says so on its line); [control] is the");
    let _ = writeln!(h, "# base's, the drive's belief, but for the load the user states for it");
    let _ = writeln!(h, "# (startup.expected_load_force_n). Tolerances: stiffness ±{:.0} %,", spec.stiffness_tol * 100.0);
    let _ = writeln!(
        h,
        "# friction ±{:.0} %, payload {:.0}–{:.0} % of rated, inertia ±{:.0} %, R {:+.0}…{:+.0} %,",
        spec.friction_tol * 100.0,
        spec.payload_min * 100.0,
        spec.payload_max * 100.0,
        spec.inertia_tol * 100.0,
        (spec.resistance_min - 1.0) * 100.0,
        (spec.resistance_max - 1.0) * 100.0
    );
    let _ = writeln!(
        h,
        "# L ±{:.0} %, flux {:+.0}…{:+.0} %, lead error ±{:.1} µm/300 mm, encoder zero anywhere",
        spec.inductance_tol * 100.0,
        (spec.flux_min - 1.0) * 100.0,
        (spec.flux_max - 1.0) * 100.0,
        spec.lead_error_max * 0.3e6
    );
    let _ = writeln!(h, "# (docs/plant.md, \"Rig families\"). This rig ({}):", m.kind);
    let _ = writeln!(
        h,
        "#   structure stiffness ×{:.4}, Coulomb friction ×{:.4}, viscous friction ×{:.4},",
        d.stiffness, d.coulomb, d.viscous
    );
    let _ = writeln!(
        h,
        "#   screw friction coefficient μ ×{:.4} (efficiency {:.4}), payload ×{:.4} ({:.2} kg),",
        d.screw_mu, rig.plant.screw.efficiency, d.payload, rig.plant.rod.payload_mass_kg
    );
    let _ = writeln!(
        h,
        "#   inertia ×{:.4}, resistance ×{:.4}, inductance ×{:.4}, flux ×{:.4},",
        d.inertia, d.resistance, d.inductance, d.flux
    );
    let _ = writeln!(
        h,
        "#   lead error {:+.2} µm/300 mm, encoder zero {:.4} rad.",
        rig.plant.screw.lead_error_m_per_m * 0.3e6,
        rig.plant.sensors.encoder_zero_rad
    );
    let _ = writeln!(h, "# The plant takes {} RK4 step(s) per PWM period here (its own choice).", rig.plant.substeps());
    h.push('\n');
    Ok(h + &doc.to_string())
}

/// Walks `old` and `new` (the same shape) and writes every leaf that
/// differs into `table`, annotated with the base value and the ratio.
fn set_changed(table: &mut dyn toml_edit::TableLike, old: &toml::Value, new: &toml::Value, path: &str) -> Result<()> {
    let (Some(old), Some(new)) = (old.as_table(), new.as_table()) else {
        bail!("{path}: expected a table");
    };
    for (key, nv) in new {
        let ov = old.get(key);
        if ov == Some(nv) {
            continue;
        }
        let here = format!("{path}.{key}");
        match nv {
            toml::Value::Table(_) => {
                let item = table.entry(key).or_insert(toml_edit::table());
                let sub = item.as_table_like_mut().ok_or_else(|| anyhow!("{here}: not a table in the base file"))?;
                let empty = toml::Value::Table(Default::default());
                set_changed(sub, ov.unwrap_or(&empty), nv, &here)?;
            }
            toml::Value::Float(x) => {
                let note = match ov.and_then(toml::Value::as_float) {
                    Some(b) if b != 0.0 => format!(" # family draw: base {b} (×{:.4})", x / b),
                    Some(b) => format!(" # family draw: base {b}"),
                    None => " # family draw (absent in the base)".to_string(),
                };
                let mut v = toml_edit::Value::from(*x);
                v.decor_mut().set_suffix(note);
                table.insert(key, toml_edit::Item::Value(v));
            }
            other => bail!("{here}: the generator changed a {} value, which it never draws", other.type_str()),
        }
    }
    Ok(())
}
