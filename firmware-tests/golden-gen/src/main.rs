//! Writes the golden vectors of the control core from the host build, or
//! checks that the committed ones are what the host build gives now.
//!
//! ```sh
//! cd firmware-tests/golden-gen
//! cargo run --release                 # (re)writes ../golden/data/*.bin
//! cargo run --release -- --check      # exit 1 if any file would change
//! ```
//!
//! The target side (`firmware-tests/tests/golden.rs`, in QEMU) replays the
//! inputs of these files and compares its outputs with the host's.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use golden::{header, ClosedLoop, Column, Family, Foc, Observer, Observer5, Table, Trajectory};

fn encode<F: Family>() -> Vec<u8> {
    let mut words: Vec<u32> = Vec::new();
    let mut rows = 0usize;
    F::generate(&mut |input, output| {
        assert_eq!(input.len(), F::IN_WORDS, "{}: input width", F::NAME);
        assert_eq!(output.len(), F::COLUMNS.len(), "{}: output width", F::NAME);
        words.extend_from_slice(input);
        words.extend_from_slice(output);
        rows += 1;
    });
    let mut bytes = Vec::with_capacity(4 * (words.len() + 6));
    for x in header(F::ID, rows, F::IN_WORDS, F::COLUMNS.len())
        .iter()
        .chain(words.iter())
    {
        bytes.extend_from_slice(&x.to_le_bytes());
    }
    bytes
}

/// Column-by-column differences between two tables of one family.
fn describe_changes(columns: &[Column], old: &Table, new: &Table) -> String {
    if old.rows != new.rows || old.in_words != new.in_words || old.out_words != new.out_words {
        return format!(
            "shape {}x({}+{}) -> {}x({}+{})",
            old.rows, old.in_words, old.out_words, new.rows, new.in_words, new.out_words
        );
    }
    let mut parts = Vec::new();
    let inputs_changed = (0..new.rows)
        .filter(|&r| (0..new.in_words).any(|c| old.input(r, c) != new.input(r, c)))
        .count();
    if inputs_changed > 0 {
        parts.push(format!("inputs of {inputs_changed} rows"));
    }
    for (c, col) in columns.iter().enumerate() {
        let changed = (0..new.rows)
            .filter(|&r| old.output(r, c) != new.output(r, c))
            .count();
        if changed > 0 {
            let first = (0..new.rows)
                .find(|&r| old.output(r, c) != new.output(r, c))
                .unwrap_or(0);
            let (a, b) = (old.output(first, c), new.output(first, c));
            let shown = if col.float {
                format!("{:e} -> {:e}", f32::from_bits(a), f32::from_bits(b))
            } else {
                format!("{a} -> {b}")
            };
            parts.push(format!(
                "{}: {changed} rows (first: row {first}, {shown})",
                col.name
            ));
        }
    }
    parts.join("; ")
}

/// The recorded closed-loop run must be a healthy one (a sequence that
/// faulted would test the bridge-off path only): no fault while enabled,
/// and the move ends near its target plus the shifts.
fn closed_loop_health(bytes: &[u8]) -> Result<String, String> {
    let t = Table::parse(bytes).map_err(|e| e.to_string())?;
    let enable = 3;
    let faults = 4;
    let position = 7;
    let mut enabled = 0usize;
    for r in 0..t.rows {
        if t.output(r, faults) != 0 {
            return Err(format!(
                "closed_loop: fault bits {:#x} at period {r}",
                t.output(r, faults)
            ));
        }
        enabled += (t.output(r, enable) != 0) as usize;
    }
    let last_enabled = (0..t.rows)
        .rev()
        .find(|&r| t.output(r, enable) != 0)
        .ok_or("closed_loop: never enabled")?;
    let x = f32::from_bits(t.output(last_enabled, position));
    if !(0.1099..=0.1105).contains(&x) {
        return Err(format!(
            "closed_loop: ended at {x} m, not near the 0.11 m target"
        ));
    }
    Ok(format!(
        "{enabled} periods enabled, no fault, ends at {x:.6} m"
    ))
}

fn run<F: Family>(dir: &Path, check: bool) -> Result<bool, String> {
    let path = dir.join(format!("{}.bin", F::NAME));
    let new = encode::<F>();
    let rows = Table::parse(&new)
        .map_err(|e| format!("{}: {e}", F::NAME))?
        .rows;
    if F::ID == ClosedLoop::ID {
        let health = closed_loop_health(&new)?;
        println!("{:<12} recorded run: {health}", F::NAME);
    }
    if check {
        let old = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        if old == new {
            println!(
                "{:<12} {:>6} rows  up to date ({})",
                F::NAME,
                rows,
                path.display()
            );
            return Ok(true);
        }
        let what = match Table::parse(&old) {
            Ok(t) => describe_changes(
                F::COLUMNS,
                &t,
                &Table::parse(&new).map_err(|e| e.to_string())?,
            ),
            Err(e) => format!("committed file unreadable: {e}"),
        };
        println!(
            "{:<12} {:>6} rows  OUT OF DATE ({}): {what}",
            F::NAME,
            rows,
            path.display()
        );
        Ok(false)
    } else {
        std::fs::write(&path, &new).map_err(|e| format!("{}: {e}", path.display()))?;
        println!(
            "{:<12} {:>6} rows  written to {} ({} bytes)",
            F::NAME,
            rows,
            path.display(),
            new.len()
        );
        Ok(true)
    }
}

fn main() -> ExitCode {
    let mut check = false;
    let mut dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../golden/data");
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--check" => check = true,
            "--dir" => match args.next() {
                Some(d) => dir = PathBuf::from(d),
                None => {
                    eprintln!("error: --dir needs a folder");
                    return ExitCode::from(2);
                }
            },
            "-h" | "--help" => {
                println!("usage: golden-gen [--check] [--dir FOLDER]   (default folder: firmware-tests/golden/data)");
                return ExitCode::SUCCESS;
            }
            other => {
                eprintln!("error: unknown argument `{other}` (try --help)");
                return ExitCode::from(2);
            }
        }
    }
    if !check {
        if let Err(e) = std::fs::create_dir_all(&dir) {
            eprintln!("error: {}: {e}", dir.display());
            return ExitCode::FAILURE;
        }
    }
    let results = [
        run::<Foc>(&dir, check),
        run::<Trajectory>(&dir, check),
        run::<ClosedLoop>(&dir, check),
        run::<Observer>(&dir, check),
        run::<Observer5>(&dir, check),
    ];
    let mut ok = true;
    for r in results {
        match r {
            Ok(fresh) => ok &= fresh,
            Err(e) => {
                eprintln!("error: {e}");
                ok = false;
            }
        }
    }
    if check && !ok {
        eprintln!(
            "golden vectors are out of date with the control core: regenerate with\n  \
             cd firmware-tests/golden-gen && cargo run --release\nand review the change (the tables record the host build's numbers)."
        );
    }
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
