//! Files that a glTF buffer or a tileset content names by URI (glTF 2.0 §3.6.1.1 "URIs": a
//! relative reference resolved against the glTF file). Only relative paths that stay inside the
//! naming file's folder are followed (no absolute path, no `..`, no symbolic link out of it,
//! no other scheme), only regular files are opened, and never more than the declared length is
//! read: a `uri` of `/dev/zero` or `/etc/passwd` is an error, not a read.

use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// Resolves `uri` (percent-encoded, `/`-separated) against the folder of `base_file`.
pub(crate) fn resolve(base_file: &Path, uri: &str) -> Result<PathBuf, String> {
    if uri.is_empty() {
        return Err("an empty uri".into());
    }
    if uri.contains(':') {
        return Err(format!(
            "uri {uri:?}: only relative file names are followed (no scheme, drive or absolute path)"
        ));
    }
    let decoded = urlencoding::decode(uri)
        .map_err(|_| format!("uri {uri:?}: its percent-encoding is not UTF-8"))?;
    if decoded.starts_with('/') || decoded.starts_with('\\') || decoded.contains('\0') {
        return Err(format!("uri {uri:?} is an absolute path"));
    }
    let relative = Path::new(&*decoded);
    for c in relative.components() {
        match c {
            Component::Normal(_) | Component::CurDir => {}
            _ => {
                return Err(format!(
                    "uri {uri:?} leaves the folder of {} (`..` or a root)",
                    base_file.display()
                ));
            }
        }
    }
    Ok(base_dir(base_file).join(relative))
}

/// Reads at most `limit` bytes of the regular file `path`, which must lie inside `dir` once
/// symbolic links are resolved; `exact` also fails when the file is shorter than `limit`.
pub(crate) fn read_inside(
    dir: &Path,
    path: &Path,
    limit: u64,
    exact: bool,
) -> Result<Vec<u8>, String> {
    let shown = path.display();
    let real = std::fs::canonicalize(path).map_err(|e| format!("{shown}: {e}"))?;
    let real_dir = std::fs::canonicalize(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    if !real.starts_with(&real_dir) {
        return Err(format!(
            "{shown} resolves to {}, outside the folder {}",
            real.display(),
            real_dir.display()
        ));
    }
    // Checked before opening: opening a named pipe would wait for a writer.
    let meta = std::fs::metadata(&real).map_err(|e| format!("{shown}: {e}"))?;
    if !meta.is_file() {
        return Err(format!("{shown} is not a regular file"));
    }
    let file = std::fs::File::open(&real).map_err(|e| format!("{shown}: {e}"))?;
    if exact && meta.len() < limit {
        return Err(format!(
            "{shown} has {} bytes, {limit} are declared",
            meta.len()
        ));
    }
    let mut data = Vec::with_capacity(limit.min(meta.len()) as usize);
    file.take(limit)
        .read_to_end(&mut data)
        .map_err(|e| format!("{shown}: {e}"))?;
    if exact && (data.len() as u64) < limit {
        return Err(format!(
            "{shown}: only {} of {limit} declared bytes could be read",
            data.len()
        ));
    }
    Ok(data)
}

/// The folder `resolve` resolves against.
pub(crate) fn base_dir(base_file: &Path) -> &Path {
    match base_file.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_relative_names_inside_the_folder_resolve() {
        let base = Path::new("/data/set/city.gltf");
        assert_eq!(
            resolve(base, "bin/a%20b.bin").unwrap(),
            Path::new("/data/set/bin/a b.bin")
        );
        assert_eq!(
            resolve(Path::new("city.gltf"), "a.bin").unwrap(),
            Path::new("./a.bin")
        );
        for bad in [
            "/dev/zero",
            "/etc/passwd",
            "../secret.bin",
            "bin/../../x",
            "file:///etc/passwd",
            "http://example.invalid/a.bin",
            "C:\\x.bin",
            "%2Fetc%2Fpasswd",
            "%2E%2E/x",
            "%FF.bin",
            "",
        ] {
            assert!(resolve(base, bad).is_err(), "{bad:?} resolved");
        }
    }
}
