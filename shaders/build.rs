//! Composes and validates every WGSL file under `wgsl/` with naga, so that a broken shader fails
//! `cargo build` with a readable message naming the file and the line.
//!
//! Composition: every shader is prefixed with the constants of `src/constants.rs` (emitted as
//! WGSL `const`s, so they are defined once in Rust) and, for the top-level files, with all of
//! `wgsl/shared/*.wgsl` (shared structs and helpers). Shared files are validated on their own
//! (with the constants), top-level files composed. The composed sources are written to
//! `$OUT_DIR/<name>.wgsl` and included by `src/lib.rs`, the prelude alone (constants and shared
//! files) to `$OUT_DIR/shared.wgsl`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

#[expect(
    dead_code,
    reason = "the build script emits the constants; the helpers are the crate's"
)]
mod constants {
    include!("src/constants.rs");
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = root.join("wgsl");
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo::rerun-if-changed={}", dir.display());
    println!(
        "cargo::rerun-if-changed={}",
        root.join("src/constants.rs").display()
    );
    let mut files = Vec::new();
    collect_wgsl(&dir, &mut files);
    files.sort();
    let shared_dir = dir.join("shared");
    let (shared, top): (Vec<PathBuf>, Vec<PathBuf>) =
        files.into_iter().partition(|p| p.starts_with(&shared_dir));

    let prelude = constants_wgsl();
    let mut failures = Vec::new();
    let mut shared_source = String::new();
    for path in &shared {
        println!("cargo::rerun-if-changed={}", path.display());
        match std::fs::read_to_string(path) {
            Ok(source) => {
                let composed = format!("{prelude}{source}");
                if let Err(m) = validate(&composed, path, prelude.lines().count()) {
                    failures.push(m);
                }
                let _ = writeln!(shared_source, "// ---- {} ----", rel(path, &dir));
                shared_source.push_str(&source);
                shared_source.push('\n');
            }
            Err(e) => failures.push(format!("{}: {e}", path.display())),
        }
    }
    let header = format!("{prelude}{shared_source}");
    if let Err(e) = std::fs::write(out_dir.join("shared.wgsl"), &header) {
        failures.push(format!("shared.wgsl: {e}"));
    }
    for path in &top {
        println!("cargo::rerun-if-changed={}", path.display());
        let source = match std::fs::read_to_string(path) {
            Ok(s) => s,
            Err(e) => {
                failures.push(format!("{}: {e}", path.display()));
                continue;
            }
        };
        let composed = format!("{header}// ---- {} ----\n{source}", rel(path, &dir));
        let offset = header.lines().count() + 1;
        if let Err(m) = validate(&composed, path, offset) {
            failures.push(m);
        }
        let out = out_dir.join(rel(path, &dir).replace('/', "_"));
        if let Err(e) = std::fs::write(&out, &composed) {
            failures.push(format!("{}: {e}", out.display()));
        }
    }
    if !failures.is_empty() {
        for f in &failures {
            eprintln!("{f}");
        }
        panic!(
            "{} WGSL file(s) failed naga validation:\n{}",
            failures.len(),
            failures.join("\n")
        );
    }
}

/// The constants of `src/constants.rs` as WGSL.
fn constants_wgsl() -> String {
    let mut s = String::from("// ---- constants (generated from shaders/src/constants.rs) ----\n");
    for (name, value) in constants::WGSL_U32 {
        let _ = writeln!(s, "const {name}: u32 = {value}u;");
    }
    for (name, value) in constants::WGSL_F32 {
        let _ = writeln!(s, "const {name}: f32 = {value:?};");
    }
    s
}

fn rel(path: &Path, dir: &Path) -> String {
    path.strip_prefix(dir)
        .unwrap_or(path)
        .to_string_lossy()
        .replace('\\', "/")
}

fn collect_wgsl(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect_wgsl(&path, out);
        } else if path.extension().is_some_and(|e| e == "wgsl") {
            out.push(path);
        }
    }
}

/// Parses and validates `composed`; on error, the message names `path` and says how many
/// generated lines precede the file's own first line.
fn validate(composed: &str, path: &Path, offset_lines: usize) -> Result<(), String> {
    let name = format!(
        "{} (composed: the file's line 1 is line {})",
        path.display(),
        offset_lines + 1
    );
    let module = naga::front::wgsl::parse_str(composed)
        .map_err(|e| e.emit_to_string_with_path(composed, &name))?;
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .map_err(|e| e.emit_to_string_with_path(composed, &name))?;
    Ok(())
}
