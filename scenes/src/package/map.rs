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
        let sections = format::verify_releasing(&map, &|bytes| release_resident(&map, bytes))
            .map_err(|e| match e {
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

    /// The parts and tags of building `index` alone, read from the mapping
    /// ([`format::read_building_details`]): for a package decoded without them.
    pub fn building_details(&self, index: usize) -> Result<format::BuildingDetails, PackageError> {
        format::read_building_details(&self.map, &self.sections, index)
    }

    /// Decodes the whole package; its GPU scene stays in the mapping (which it keeps alive).
    pub fn decode(&self) -> Result<ScenePackage, PackageError> {
        format::decode_mapped(&self.map, &self.sections, format::Decode::All)
    }

    /// Decodes the sections `what` names (see [`format::Decode`]); the GPU scene stays in the
    /// mapping. The other sections' pages are given back once decoded.
    pub fn decode_as(&self, what: format::Decode) -> Result<ScenePackage, PackageError> {
        let package = format::decode_mapped(&self.map, &self.sections, what);
        let gpu_scene = format::SectionKind::GpuScene as u32;
        for e in self.sections.iter().filter(|e| e.kind != gpu_scene) {
            let range = e.offset as usize..(e.offset + e.length) as usize;
            if let Some(bytes) = self.map.get(range) {
                release_resident(&self.map, bytes);
            }
        }
        package
    }
}

/// Gives back to the system the pages of `map` that hold `bytes` (no-op where `bytes` is not
/// part of `map`): they leave the process's resident memory and stay in the page cache, so a
/// later read of them costs a minor fault. Opening a package touches each byte once (checksum,
/// decode, upload to the GPU), and a gigabyte package must not stay resident because of it.
#[expect(
    unsafe_code,
    reason = "MADV_DONTNEED is an unchecked advice in memmap2: on a writable private mapping it \
              would discard writes"
)]
pub(crate) fn release_resident(map: &memmap2::Mmap, bytes: &[u8]) {
    let start = (bytes.as_ptr() as usize).wrapping_sub(map.as_ptr() as usize);
    if start > map.len() || bytes.len() > map.len() - start {
        return;
    }
    // SAFETY: `map` is a read-only shared mapping of a file nobody writes (a package, see
    // `map_read_only`, or a finished scratch file, see `super::scratch`); MADV_DONTNEED drops
    // this process's pages of it, and the next read maps the file's unchanged bytes again, so
    // every `&[u8]` into the mapping keeps its value (neighbouring bytes on the same pages
    // included).
    #[cfg(unix)]
    if let Err(e) = unsafe {
        map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, start, bytes.len())
    } {
        tracing::debug!("madvise(DONTNEED) on a package mapping failed: {e}");
    }
}

/// The memory maps a borrowed view's arrays lie in (none for arrays in memory), so that the
/// view can give back the pages of bytes it is done with ([`release_resident`]).
#[derive(Clone, Copy, Default)]
pub(crate) struct MappedPages<'a>([Option<&'a memmap2::Mmap>; 3]);

impl<'a> MappedPages<'a> {
    pub(crate) fn one(map: &'a memmap2::Mmap) -> MappedPages<'a> {
        MappedPages([Some(map), None, None])
    }

    pub(crate) fn of(maps: [Option<&'a memmap2::Mmap>; 3]) -> MappedPages<'a> {
        MappedPages(maps)
    }

    /// The first map, if any.
    pub(crate) fn first(&self) -> Option<&'a memmap2::Mmap> {
        self.0.iter().flatten().next().copied()
    }

    /// Releases the pages of `bytes` ([`release_resident`]) where they lie in one of the maps;
    /// bytes in memory are left as they are.
    pub(crate) fn release_resident(&self, bytes: &[u8]) {
        for map in self.0.iter().flatten() {
            release_resident(map, bytes);
        }
    }
}

impl std::fmt::Debug for MappedPages<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(if self.first().is_some() {
            "mapped"
        } else {
            "owned"
        })
    }
}

/// Views of the same arrays are equal wherever their bytes live.
impl PartialEq for MappedPages<'_> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Bytes written out between two releases of their pages ([`write_releasing`]).
pub(crate) const RELEASE_PIECE: usize = 32 << 20;

/// Writes `bytes` to `out` [`RELEASE_PIECE`] bytes at a time; where they lie in `map`, each
/// piece's pages leave resident memory once written (a gigabyte section read from a mapping
/// to be written is never resident whole).
pub(crate) fn write_releasing(
    map: Option<&memmap2::Mmap>,
    bytes: &[u8],
    out: &mut impl std::io::Write,
) -> std::io::Result<()> {
    for piece in bytes.chunks(RELEASE_PIECE) {
        out.write_all(piece)?;
        if let Some(map) = map {
            release_resident(map, piece);
        }
    }
    Ok(())
}

/// Maps a file read-only.
#[expect(
    unsafe_code,
    reason = "memmap2::Mmap::map is unsafe because another process could change the file \
              while it is mapped; this is the only unsafe call of the package reader"
)]
pub(crate) fn map_read_only(file: &std::fs::File) -> std::io::Result<memmap2::Mmap> {
    // SAFETY: the mapping is read-only and only ever read as `&[u8]`, or through
    // `bytemuck::cast_slice` as `Pod` arrays (for which every bit pattern is valid): every
    // section is checksummed before it is decoded and decoding validates it, so a file changed
    // underneath us can at worst produce a checksum or decode error or wrong numbers, not
    // undefined behaviour in our code. An input file mapped by a loader is parsed as bytes the
    // same way: a change underneath gives a parse error or other numbers. Truncation of the file while
    // mapped (SIGBUS) is the documented hazard of memory maps that callers accept by
    // reading packages (and inputs) they own.
    unsafe { memmap2::Mmap::map(file) }
}
