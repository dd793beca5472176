//! Scratch space on disk for a section too large to keep resident while it is built: the GPU
//! scene, a gigabyte at a million buildings. Its bytes are written through a shared mapping of
//! an unnamed file, and the written pages are handed to the page cache batch by batch, so the
//! process holds only the batch being written; the package is later written from the mapping,
//! a few megabytes at a time. The file disappears with the mapping (nothing is left behind, even
//! when the process is killed). Finished sections are spilled the same way
//! ([`SpilledSection`]).

use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use super::{PackageError, SectionKind};
use crate::occluder::{Occluder, OccluderOutcome};

/// A writable shared mapping of an unnamed scratch file.
pub(super) struct ScratchMap {
    map: memmap2::MmapMut,
}

/// Gives the pages written so far back to the page cache ([`ScratchMap::fill_with`]).
pub(super) struct Releaser {
    start: usize,
    len: usize,
}

impl ScratchMap {
    /// An unnamed file of `len` zero bytes in `dir`, its blocks reserved where the file system
    /// can (a full disk is an error here, not a `SIGBUS` when a page is first written), mapped
    /// for writing.
    /// The error names `dir`.
    pub(super) fn new_in(dir: &Path, len: usize) -> io::Result<ScratchMap> {
        let made = tempfile::tempfile_in(dir).and_then(|file| {
            reserve(&file, len as u64)?;
            map_shared(&file)
        });
        match made {
            Ok(map) => Ok(ScratchMap { map }),
            Err(e) => Err(io::Error::new(
                e.kind(),
                format!("{} bytes in {}: {e}", len, dir.display()),
            )),
        }
    }

    /// Runs `fill` on the mapping's bytes; `fill` calls [`Releaser::release`] whenever what it
    /// wrote may leave resident memory (between batches: what it writes next refaults from the
    /// page cache if it shares a page with what was released).
    pub(super) fn fill_with<R>(&mut self, fill: impl FnOnce(&mut [u8], &Releaser) -> R) -> R {
        let releaser = Releaser {
            start: self.map.as_ptr() as usize,
            len: self.map.len(),
        };
        fill(&mut self.map[..], &releaser)
    }

    /// The mapping, read-only from now on.
    pub(super) fn into_read_only(self) -> io::Result<memmap2::Mmap> {
        self.map.make_read_only()
    }
}

/// Reserves `len` bytes for `file` (`fallocate`), or sets its length where the file system
/// cannot reserve (then a full disk shows when a page is written back).
fn reserve(file: &std::fs::File, len: u64) -> io::Result<()> {
    #[cfg(target_os = "linux")]
    match rustix::fs::fallocate(file, rustix::fs::FallocateFlags::empty(), 0, len) {
        Ok(()) => return Ok(()),
        Err(e) if e == rustix::io::Errno::OPNOTSUPP => {}
        Err(e) => return Err(e.into()),
    }
    file.set_len(len)
}

#[expect(
    unsafe_code,
    reason = "memmap2::MmapMut::map_mut is unsafe because another process could change or \
              truncate the file while it is mapped"
)]
fn map_shared(file: &std::fs::File) -> io::Result<memmap2::MmapMut> {
    // SAFETY: the file is unnamed (no other process can open it) and its length is never
    // changed after this; the mapping is the only way its bytes are read or written.
    unsafe { memmap2::MmapMut::map_mut(file) }
}

impl Releaser {
    /// Drops the mapping's pages from this process's resident memory. Their bytes stay in the
    /// page cache (a shared file mapping), written back to the scratch file in time, and a later
    /// read or write maps them again.
    #[expect(
        unsafe_code,
        reason = "madvise(MADV_DONTNEED) through a raw address: the mapping is borrowed mutably \
                  by the writer meanwhile"
    )]
    pub(super) fn release(&self) {
        #[cfg(target_os = "linux")]
        // SAFETY: `start..start + len` is the whole of a live shared file mapping
        // (`fill_with` lends `self` only while its `ScratchMap` is borrowed). MADV_DONTNEED on a
        // shared file mapping does not discard data: dirty pages go to the page cache and every
        // later access sees the file's current bytes, so the writer's slices keep their values.
        if let Err(e) = unsafe {
            rustix::mm::madvise(
                self.start as *mut std::ffi::c_void,
                self.len,
                rustix::mm::Advice::LinuxDontNeed,
            )
        } {
            tracing::debug!("madvise(DONTNEED) on a scratch mapping failed: {e}");
        }
    }
}

/// A scratch file being appended to ([`ScratchBytes`] once finished).
#[derive(Debug)]
pub(crate) struct ScratchWriter {
    out: io::BufWriter<std::fs::File>,
}

impl ScratchWriter {
    /// An unnamed file in `dir`.
    pub(crate) fn new_in(dir: &Path) -> io::Result<ScratchWriter> {
        Ok(ScratchWriter {
            out: io::BufWriter::with_capacity(1 << 16, tempfile::tempfile_in(dir)?),
        })
    }

    /// The bytes written, mapped read-only.
    pub(crate) fn finish(self) -> io::Result<ScratchBytes> {
        let file = self.out.into_inner().map_err(|e| e.into_error())?;
        let map = if file.metadata()?.len() == 0 {
            None
        } else {
            Some(Arc::new(super::map::map_read_only(&file)?))
        };
        Ok(ScratchBytes { map })
    }
}

impl io::Write for ScratchWriter {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.out.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
}

/// The bytes of a finished scratch file, mapped (none for an empty file: nothing to map).
#[derive(Clone)]
pub(crate) struct ScratchBytes {
    map: Option<Arc<memmap2::Mmap>>,
}

impl ScratchBytes {
    /// The bytes, from a page boundary (so any array type can be viewed in them).
    pub(crate) fn bytes(&self) -> &[u8] {
        self.map.as_deref().map_or(&[], |m| &m[..])
    }

    /// The mapping the bytes lie in (none when empty).
    pub(crate) fn map(&self) -> Option<&memmap2::Mmap> {
        self.map.as_deref()
    }

    /// Writes the bytes to `out` a piece at a time, each piece's pages leaving resident memory
    /// once written.
    fn write_to(&self, out: &mut impl io::Write) -> io::Result<()> {
        super::map::write_releasing(self.map.as_deref(), self.bytes(), out)
    }
}

/// A section encoded ahead of the package's write into an unnamed scratch file, so that its
/// value need not stay in memory while later stages run; the package writer copies its bytes
/// (the same bytes the value would have been encoded to) a few megabytes at a time.
#[derive(Clone)]
pub struct SpilledSection {
    kind: SectionKind,
    payload: ScratchBytes,
}

impl SpilledSection {
    /// Encodes `value` as section `kind` into a scratch file in `dir`. `value` must be of the
    /// section's type (see [`SectionKind`]).
    pub fn encode<T: Serialize>(
        kind: SectionKind,
        value: &T,
        dir: &Path,
    ) -> Result<SpilledSection, PackageError> {
        let io = |e| scratch_error(kind, dir, e);
        let mut out = ScratchWriter::new_in(dir).map_err(io)?;
        postcard::to_io(value, &mut out).map_err(|e| encode_error(kind, e))?;
        Ok(SpilledSection {
            kind,
            payload: out.finish().map_err(io)?,
        })
    }

    pub fn kind(&self) -> SectionKind {
        self.kind
    }

    /// The encoded payload.
    pub fn bytes(&self) -> &[u8] {
        self.payload.bytes()
    }

    /// Writes the payload to `out` ([`ScratchBytes`]: its pages released as written).
    pub(super) fn write_payload(&self, out: &mut impl io::Write) -> io::Result<()> {
        self.payload.write_to(out)
    }
}

/// The occluder set's section encoded as the set's occluders are built, the set never whole
/// in memory (a gigabyte at a million buildings): the occluders go to one scratch file chunk
/// by chunk ([`SpilledOccluderSection::push`]); once their number is known the section's bytes
/// — the number, the occluders, the outcomes, as [`SpilledSection::encode`] writes the set —
/// are copied to another.
#[derive(Debug)]
pub struct SpilledOccluderSection {
    dir: PathBuf,
    occluders: ScratchWriter,
    count: usize,
}

impl SpilledOccluderSection {
    /// An unnamed file in `dir`.
    pub fn new_in(dir: &Path) -> Result<SpilledOccluderSection, PackageError> {
        Ok(SpilledOccluderSection {
            dir: dir.to_path_buf(),
            occluders: ScratchWriter::new_in(dir)
                .map_err(|e| scratch_error(SectionKind::Occluders, dir, e))?,
            count: 0,
        })
    }

    /// Encodes `occluders`, the set's next ones.
    pub fn push(&mut self, occluders: &[Occluder]) -> Result<(), PackageError> {
        for o in occluders {
            postcard::to_io(o, &mut self.occluders)
                .map_err(|e| encode_error(SectionKind::Occluders, e))?;
        }
        self.count += occluders.len();
        Ok(())
    }

    /// The section of the set whose occluders were pushed and whose outcomes are
    /// `per_building`.
    pub fn finish(self, per_building: &[OccluderOutcome]) -> Result<SpilledSection, PackageError> {
        let dir = &self.dir;
        let io = |e| scratch_error(SectionKind::Occluders, dir, e);
        let encode = |e| encode_error(SectionKind::Occluders, e);
        let occluders = self.occluders.finish().map_err(io)?;
        let mut out = ScratchWriter::new_in(dir).map_err(io)?;
        // A sequence's length is the varint of a `usize`, as postcard writes one.
        postcard::to_io(&self.count, &mut out).map_err(encode)?;
        occluders.write_to(&mut out).map_err(io)?;
        drop(occluders);
        postcard::to_io(per_building, &mut out).map_err(encode)?;
        Ok(SpilledSection {
            kind: SectionKind::Occluders,
            payload: out.finish().map_err(io)?,
        })
    }
}

/// Section `kind` could not be written to a scratch file in `dir`.
fn scratch_error(kind: SectionKind, dir: &Path, e: io::Error) -> PackageError {
    PackageError::Encode {
        section: kind.name().into(),
        reason: format!("scratch file in {}: {e}", dir.display()),
    }
}

/// Section `kind` could not be encoded.
fn encode_error(kind: SectionKind, e: postcard::Error) -> PackageError {
    PackageError::Encode {
        section: kind.name().into(),
        reason: e.to_string(),
    }
}

impl PartialEq for SpilledSection {
    fn eq(&self, other: &SpilledSection) -> bool {
        self.kind == other.kind && self.bytes() == other.bytes()
    }
}

impl std::fmt::Debug for SpilledSection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SpilledSection")
            .field("kind", &self.kind)
            .field("bytes", &self.bytes().len())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pages released while a writer still holds the mapping keep what was written: the next
    /// write to a released page, and every read after, see the bytes written before.
    #[test]
    fn released_pages_keep_their_bytes() {
        let dir = tempfile::tempdir().expect("temp dir");
        let len = 3 << 20;
        let mut scratch = ScratchMap::new_in(dir.path(), len).expect("scratch file");
        let value = |i: usize| (i.wrapping_mul(2_654_435_761) >> 7) as u8;
        scratch.fill_with(|bytes, pages| {
            assert!(
                bytes.iter().all(|&b| b == 0),
                "a new scratch file is zeroed"
            );
            // Halves written with a release between, the second half's first byte on a page
            // the first half also wrote.
            let half = len / 2 + 123;
            for (i, b) in bytes[..half].iter_mut().enumerate() {
                *b = value(i);
            }
            pages.release();
            for (i, b) in bytes.iter_mut().enumerate().skip(half) {
                *b = value(i);
            }
            pages.release();
            assert!(bytes.iter().enumerate().all(|(i, &b)| b == value(i)));
        });
        let map = scratch.into_read_only().expect("read-only");
        assert!(map.iter().enumerate().all(|(i, &b)| b == value(i)));
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("list").collect();
        assert!(left.is_empty(), "the scratch file has no name: {left:?}");
    }

    #[test]
    fn a_missing_folder_is_an_error_that_names_it() {
        let dir = tempfile::tempdir().expect("temp dir");
        let missing = dir.path().join("nowhere");
        let err = ScratchMap::new_in(&missing, 4096)
            .err()
            .expect("no scratch file in a missing folder");
        assert!(
            err.to_string().contains(&missing.display().to_string()),
            "{err}"
        );
    }
}
