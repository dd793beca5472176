//! Reading a package through a memory map.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{PackageError, ScenePackage, format};

/// A package file mapped into memory, its header and checksums verified; sections are
/// decoded on demand straight from the mapping.
#[derive(Debug)]
pub struct PackageFile {
    path: PathBuf,
    map: Arc<memmap2::Mmap>,
    sections: Vec<format::SectionEntry>,
}

impl PackageFile {
    /// Maps `path` and verifies its header, section table and every section's checksum.
    pub fn open(path: &Path) -> Result<PackageFile, PackageError> {
        let io = |source| PackageError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = std::fs::File::open(path).map_err(io)?;
        let map = map_read_only(&file).map_err(io)?;
        let sections = format::verify(&map).map_err(|e| match e {
            PackageError::Version {
                path: None,
                found,
                supported,
            } => PackageError::Version {
                path: Some(path.to_path_buf()),
                found,
                supported,
            },
            e => e,
        })?;
        Ok(PackageFile {
            path: path.to_path_buf(),
            map: Arc::new(map),
            sections,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The whole mapped file.
    pub fn bytes(&self) -> &[u8] {
        &self.map
    }

    /// The payload of one section (a slice of the mapping), if present.
    pub fn section(&self, kind: format::SectionKind) -> Option<&[u8]> {
        let e = self.sections.iter().find(|e| e.kind == kind as u32)?;
        self.map
            .get(e.offset as usize..(e.offset + e.length) as usize)
    }

    /// The verified section table.
    pub fn sections(&self) -> &[format::SectionEntry] {
        &self.sections
    }

    /// Decodes one section straight from the mapping (for example only the quadtree and the
    /// blocks), `None` when the package has no such section. `T` must be the section's type
    /// (see [`format::SectionKind`]); another type gives a decode error.
    pub fn decode_section<T: serde::de::DeserializeOwned>(
        &self,
        kind: format::SectionKind,
    ) -> Result<Option<T>, PackageError> {
        format::decode_one(&self.map, &self.sections, kind)
    }

    /// Decodes the whole package; its GPU scene stays in the mapping (which it keeps alive).
    pub fn decode(&self) -> Result<ScenePackage, PackageError> {
        format::decode_mapped(&self.map, &self.sections, format::Decode::All)
    }

    /// Decodes the sections `what` names (see [`format::Decode`]); the GPU scene stays in the
    /// mapping.
    pub fn decode_as(&self, what: format::Decode) -> Result<ScenePackage, PackageError> {
        format::decode_mapped(&self.map, &self.sections, what)
    }
}

/// Maps a file read-only.
#[expect(
    unsafe_code,
    reason = "memmap2::Mmap::map is unsafe because another process could change the file \
              while it is mapped; this is the only unsafe call of the package reader"
)]
fn map_read_only(file: &std::fs::File) -> std::io::Result<memmap2::Mmap> {
    // SAFETY: the mapping is read-only and only ever read as `&[u8]`, or through
    // `bytemuck::cast_slice` as `Pod` arrays (for which every bit pattern is valid): every
    // section is checksummed before it is decoded and decoding validates it, so a file changed
    // underneath us can at worst produce a checksum or decode error or wrong numbers, not
    // undefined behaviour in our code. Truncation of the file while
    // mapped (SIGBUS) is the documented hazard of memory maps that callers accept by
    // reading packages they own.
    unsafe { memmap2::Mmap::map(file) }
}
