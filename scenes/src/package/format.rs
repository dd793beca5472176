//! The byte layout of a scene package (all integers little-endian):
//!
//! ```text
//! 0   magic "CWK\0"
//! 4   u32 format version (FORMAT_VERSION)
//! 8   u32 section count N (at most MAX_SECTIONS)
//! 12  u32 CRC-32 (IEEE) of bytes 0..12 followed by the section table
//! 16  section table: N entries of 32 bytes, kinds strictly ascending:
//!       u32 kind, u32 flags (0), u64 offset, u64 length, u32 CRC-32 of the payload, u32 0
//! ... sections: each payload starts at a multiple of SECTION_ALIGN; the gaps are zero bytes;
//!     the file ends with the last payload.
//! ```
//!
//! Each payload is one value encoded with `postcard` (serde; varint integers, little-endian
//! floats), except the GPU scene's: raw arrays laid out as the GPU reads them
//! ([`super::gpu_scene`]). Every byte of the file is covered by a checksum or checked to be zero, so any
//! corruption is reported as an error.

use std::io::{Seek, SeekFrom, Write};
use std::sync::Arc;

use serde::Serialize;
use serde::de::DeserializeOwned;

use super::{GpuScene, GpuSceneView, PackageError, ScenePackage, StageTiming, WriteOptions};
use crate::TriangleMesh;
use crate::cluster_tree::ClusterTree;

/// The first four bytes of every package.
pub const MAGIC: [u8; 4] = *b"CWK\0";
/// The format version this build writes and reads. History:
/// - 1: first format.
/// - 2: the cluster tree's `ClusterStats` gained `merge_fallback_log` (each merge whose first
///   construction failed, with its reason); mesh cities (CityJSON, glTF) rest on the ground:
///   their frame's origin height is the lowest building base, heights are above it.
/// - 3: the GPU-ready scene section ([`super::GpuScene`]: vertices, indices, records, cull
///   parts of buildings and cluster meshes, as raw little-endian arrays read in place).
/// - 4: the provenance's load report counts streets found and lists the rejected streets
///   (`streets_found`, `streets_rejected`).
/// - 5: the GPU scene holds the drawable occluders' arrays
///   ([`crate::occluder_draws::OccluderArrays`]), so the runtime opens a package without
///   decoding the occluder set; the cluster tree section no longer repeats the cluster meshes
///   the GPU scene holds (a full decode restores them from there); the buildings' parts and
///   tags moved to a section of their own ([`SectionKind::BuildingDetails`]).
/// - 6: every cluster tree node has a geometric and a colour error
///   (`ClusterNode::geometric_error_m`, `colour_error_m`), the default LOD criterion's.
/// - 7: streets carry their tagged width (`Street::tagged_width_m`); ground areas (water,
///   parks, squares) in a section of their own ([`SectionKind::GroundAreas`]); streets and
///   ground areas as drawn triangles ([`SectionKind::GroundSurfaces`]).
/// - 8: the drawable occluders' vertices are welded per occluder (the corners a facade's walls
///   share are stored once: half the occluder vertices); a package of format 7 would still
///   draw, but fails its check against the arrays rebuilt from its buildings.
/// - 9: an optional section of baked cluster textures ([`SectionKind::ClusterTextures`],
///   Chang et al. 2008 §7).
pub const FORMAT_VERSION: u32 = 9;
/// Sections start at multiples of this (a cache line, and enough for any scalar type).
pub const SECTION_ALIGN: u64 = 64;
/// The most sections a package may have.
pub const MAX_SECTIONS: u32 = 64;
const HEADER_LEN: usize = 16;
const ENTRY_LEN: usize = 32;

/// What a section holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
#[repr(u32)]
pub enum SectionKind {
    /// [`crate::Frame`].
    Frame = 1,
    /// `Vec<Building>`: ids, source ids, footprints, parts, heights, meshes, tags.
    Buildings = 2,
    /// `Vec<Street>`.
    Streets = 3,
    /// [`crate::blocks::UrbanBlocks`].
    Blocks = 4,
    /// [`crate::quadtree::BQuadtree`].
    Quadtree = 5,
    /// [`super::Provenance`].
    Provenance = 6,
    /// [`crate::occluder::OccluderSet`] (optional).
    Occluders = 7,
    /// [`crate::cluster_tree::ClusterTree`] with its shared vertex array and cluster meshes
    /// (optional).
    ClusterTree = 8,
    /// `Vec<StageTiming>` (optional, not deterministic).
    Timings = 9,
    /// [`super::GpuScene`]: raw arrays, not postcard.
    GpuScene = 10,
    /// Per building, its parts and tags (`Vec<(Vec<BuildingPart>, Tags)>`, tags as a map),
    /// in building order): what preprocessing and inspection read and drawing does not, kept
    /// apart from the buildings so a package opened to draw does not decode them.
    BuildingDetails = 11,
    /// `Vec<GroundArea>`: water, parks, squares.
    GroundAreas = 12,
    /// [`crate::ground_surfaces::GroundSurfaces`]: streets and ground areas as drawn triangles.
    GroundSurfaces = 13,
    /// [`crate::cluster_texture::baked::ClusterTextures`]: the cluster meshes' baked textures
    /// (optional; `preprocess --cluster-textures`).
    ClusterTextures = 14,
}

impl SectionKind {
    pub const ALL: [SectionKind; 14] = [
        SectionKind::Frame,
        SectionKind::Buildings,
        SectionKind::Streets,
        SectionKind::Blocks,
        SectionKind::Quadtree,
        SectionKind::Provenance,
        SectionKind::Occluders,
        SectionKind::ClusterTree,
        SectionKind::Timings,
        SectionKind::GpuScene,
        SectionKind::BuildingDetails,
        SectionKind::GroundAreas,
        SectionKind::GroundSurfaces,
        SectionKind::ClusterTextures,
    ];

    pub fn from_u32(v: u32) -> Option<SectionKind> {
        Self::ALL.into_iter().find(|k| *k as u32 == v)
    }

    pub fn name(self) -> &'static str {
        match self {
            SectionKind::Frame => "frame",
            SectionKind::Buildings => "buildings",
            SectionKind::Streets => "streets",
            SectionKind::Blocks => "blocks",
            SectionKind::Quadtree => "quadtree",
            SectionKind::Provenance => "provenance",
            SectionKind::Occluders => "occluders",
            SectionKind::ClusterTree => "cluster tree",
            SectionKind::Timings => "timings",
            SectionKind::GpuScene => "gpu scene",
            SectionKind::BuildingDetails => "building details",
            SectionKind::GroundAreas => "ground areas",
            SectionKind::GroundSurfaces => "ground surfaces",
            SectionKind::ClusterTextures => "cluster textures",
        }
    }

    fn required(self) -> bool {
        (self as u32) <= SectionKind::Provenance as u32
            || matches!(
                self,
                SectionKind::GpuScene
                    | SectionKind::BuildingDetails
                    | SectionKind::GroundAreas
                    | SectionKind::GroundSurfaces
            )
    }
}

/// One entry of the section table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SectionEntry {
    pub kind: u32,
    pub offset: u64,
    pub length: u64,
    pub crc32: u32,
}

/// Encodes `value` into `out` as it goes (no copy of the section in memory; postcard's many
/// small writes gathered into blocks before they are checksummed).
fn encode_one<T: Serialize, W: Write>(
    kind: SectionKind,
    value: &T,
    out: &mut SectionSink<'_, W>,
) -> Result<(), PackageError> {
    let mut buffered = std::io::BufWriter::with_capacity(1 << 16, &mut *out);
    let written = postcard::to_io(value, &mut buffered).map(|_| ());
    // A failed write (kept in the sink) is reported by the caller, with its cause.
    let _ = buffered.flush();
    drop(buffered);
    match written {
        Err(e) if out.error.is_none() => Err(PackageError::Encode {
            section: kind.name().into(),
            reason: e.to_string(),
        }),
        _ => Ok(()),
    }
}

/// A section's bytes on their way to the file: counted and checksummed as they pass, and the
/// first write error kept for the caller.
struct SectionSink<'w, W> {
    out: &'w mut W,
    length: u64,
    crc: crc32fast::Hasher,
    error: Option<std::io::Error>,
}

impl<W: Write> Write for SectionSink<'_, W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self.out.write(buf) {
            Ok(n) => {
                self.crc.update(&buf[..n]);
                self.length += n as u64;
                Ok(n)
            }
            Err(e) => {
                let kind = e.kind();
                self.error.get_or_insert(e);
                Err(kind.into())
            }
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// The sections `pkg` is written with, in the file's (ascending) order.
fn sections_of(pkg: &ScenePackage, options: WriteOptions) -> Vec<SectionKind> {
    use SectionKind as K;
    let mut kinds = vec![
        K::Frame,
        K::Buildings,
        K::Streets,
        K::Blocks,
        K::Quadtree,
        K::Provenance,
    ];
    if pkg.occluders.is_some() {
        kinds.push(K::Occluders);
    }
    if pkg.cluster_tree.is_some() {
        kinds.push(K::ClusterTree);
    }
    if options.include_timings {
        kinds.push(K::Timings);
    }
    kinds.extend([
        K::GpuScene,
        K::BuildingDetails,
        K::GroundAreas,
        K::GroundSurfaces,
    ]);
    if pkg.cluster_textures.is_some() {
        kinds.push(K::ClusterTextures);
    }
    kinds.extend(pkg.spilled.iter().map(|s| s.kind()));
    kinds.sort();
    kinds.dedup();
    kinds
}

/// Writes the payload of one section of `pkg` to `out`: encoded as it is written, or the GPU
/// scene's own bytes.
fn write_payload<W: Write>(
    pkg: &ScenePackage,
    kind: SectionKind,
    out: &mut SectionSink<'_, W>,
) -> Result<(), PackageError> {
    use SectionKind as K;
    if let Some(spilled) = pkg.spilled.iter().find(|s| s.kind() == kind) {
        // A failed write is kept in the sink.
        let _ = spilled.write_payload(out);
        return Ok(());
    }
    match kind {
        K::Frame => encode_one(kind, &pkg.frame, out),
        K::Buildings => encode_one(kind, &pkg.buildings, out),
        K::Streets => encode_one(kind, &pkg.streets, out),
        K::Blocks => encode_one(kind, &pkg.blocks, out),
        K::Quadtree => encode_one(kind, &pkg.quadtree, out),
        K::Provenance => encode_one(kind, &pkg.provenance, out),
        K::Occluders => match &pkg.occluders {
            Some(occluders) => encode_one(kind, occluders, out),
            None => Err(absent(kind)),
        },
        K::ClusterTree => match &pkg.cluster_tree {
            Some(tree) => encode_one(kind, tree, out),
            None => Err(absent(kind)),
        },
        K::Timings => encode_one(kind, &pkg.timings, out),
        K::GpuScene => {
            // A failed write is kept in the sink.
            let _ = pkg.gpu_scene.write_payload(out);
            Ok(())
        }
        K::BuildingDetails => {
            let details: Vec<_> = pkg.buildings.iter().map(|b| (&b.parts, &b.tags)).collect();
            encode_one(kind, &details, out)
        }
        K::GroundAreas => encode_one(kind, &pkg.ground_areas, out),
        K::GroundSurfaces => encode_one(kind, &pkg.ground_surfaces, out),
        K::ClusterTextures => match &pkg.cluster_textures {
            Some(textures) => encode_one(kind, textures, out),
            None => Err(absent(kind)),
        },
    }
}

/// An optional section asked for though the package lacks it ([`sections_of`] never does).
fn absent(kind: SectionKind) -> PackageError {
    PackageError::Encode {
        section: kind.name().into(),
        reason: "the package has no such section".into(),
    }
}

/// Writes a package (see the module documentation) to `out` and returns its length. The
/// sections are encoded straight into `out` one at a time, counted and checksummed as they
/// pass, and the table, which needs their lengths and checksums, last: no encoded section is
/// held in memory (at a million buildings the file is gigabytes). `io` names a failed write.
pub fn encode_to<W: Write + Seek>(
    pkg: &ScenePackage,
    options: WriteOptions,
    out: &mut W,
    io: impl Fn(std::io::Error) -> PackageError,
) -> Result<u64, PackageError> {
    let kinds = sections_of(pkg, options);
    let table_end = (HEADER_LEN + ENTRY_LEN * kinds.len()) as u64;
    out.write_all(&vec![0; table_end as usize]).map_err(&io)?;
    let mut entries = Vec::with_capacity(kinds.len());
    let mut offset = table_end;
    for kind in kinds {
        let start = offset.next_multiple_of(SECTION_ALIGN);
        let gap = (start - offset) as usize;
        out.write_all(&[0; SECTION_ALIGN as usize][..gap])
            .map_err(&io)?;
        let mut sink = SectionSink {
            out: &mut *out,
            length: 0,
            crc: crc32fast::Hasher::new(),
            error: None,
        };
        write_payload(pkg, kind, &mut sink)?;
        if let Some(e) = sink.error {
            return Err(io(e));
        }
        let (length, crc32) = (sink.length, sink.crc.finalize());
        entries.push(SectionEntry {
            kind: kind as u32,
            offset: start,
            length,
            crc32,
        });
        offset = start + length;
    }
    let mut head = Vec::with_capacity(table_end as usize);
    head.extend_from_slice(&MAGIC);
    head.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    head.extend_from_slice(&(entries.len() as u32).to_le_bytes());
    head.extend_from_slice(&[0; 4]);
    for e in &entries {
        head.extend_from_slice(&e.kind.to_le_bytes());
        head.extend_from_slice(&0u32.to_le_bytes());
        head.extend_from_slice(&e.offset.to_le_bytes());
        head.extend_from_slice(&e.length.to_le_bytes());
        head.extend_from_slice(&e.crc32.to_le_bytes());
        head.extend_from_slice(&0u32.to_le_bytes());
    }
    let crc = header_crc(&head);
    head[12..16].copy_from_slice(&crc.to_le_bytes());
    out.seek(SeekFrom::Start(0)).map_err(&io)?;
    out.write_all(&head).map_err(&io)?;
    out.seek(SeekFrom::Start(offset)).map_err(&io)?;
    Ok(offset)
}

/// Encodes a package into memory ([`encode_to`]).
pub fn encode(pkg: &ScenePackage, options: WriteOptions) -> Result<Vec<u8>, PackageError> {
    let mut out = std::io::Cursor::new(Vec::new());
    encode_to(pkg, options, &mut out, |e| PackageError::Encode {
        section: "package".into(),
        reason: e.to_string(),
    })?;
    Ok(out.into_inner())
}

/// CRC-32 of the header's first 12 bytes and the section table (`bytes` starts at the header
/// and holds at least the table).
pub(super) fn header_crc(bytes: &[u8]) -> u32 {
    let count = u32_at(bytes, 8).unwrap_or(0) as usize;
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&bytes[..12]);
    hasher.update(&bytes[HEADER_LEN..HEADER_LEN + ENTRY_LEN * count]);
    hasher.finalize()
}

/// Packages at least this large decode their large sections in parallel.
const PARALLEL_DECODE_BYTES: usize = 16 << 20;
/// Bytes per checksum chunk hashed on a thread of its own.
const CRC_CHUNK: usize = 64 << 20;

/// Starts hashing `payload` (chunks of [`CRC_CHUNK`] on scoped threads, combined in order; a
/// payload of one chunk on the caller's) and returns the function that gives its CRC-32. Each
/// chunk goes to `release` once hashed.
fn payload_crc<'scope>(
    scope: &'scope std::thread::Scope<'scope, '_>,
    payload: &'scope [u8],
    release: &'scope (dyn Fn(&[u8]) + Sync),
) -> Box<dyn FnOnce() -> u32 + 'scope> {
    if payload.len() <= CRC_CHUNK {
        return Box::new(move || {
            let crc = crc32fast::hash(payload);
            release(payload);
            crc
        });
    }
    let chunks: Vec<_> = payload
        .chunks(CRC_CHUNK)
        .map(|chunk| {
            scope.spawn(move || {
                let mut h = crc32fast::Hasher::new();
                h.update(chunk);
                release(chunk);
                h
            })
        })
        .collect();
    Box::new(move || {
        let mut total = crc32fast::Hasher::new();
        for chunk in chunks {
            let h = chunk
                .join()
                .unwrap_or_else(|e| std::panic::resume_unwind(e));
            total.combine(&h);
        }
        total.finalize()
    })
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
}

fn u64_at(bytes: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
}

fn truncated(what: &str, needed: u64, len: usize) -> PackageError {
    PackageError::Truncated {
        what: what.into(),
        needed,
        len: len as u64,
    }
}

/// Verifies magic, version, header checksum, section table, padding and every section's
/// checksum; returns the section table.
pub fn verify(bytes: &[u8]) -> Result<Vec<SectionEntry>, PackageError> {
    verify_releasing(bytes, &|_| {})
}

/// [`verify`], handing each stretch of a section to `release` once its checksum has read it
/// (a memory-mapped package gives those pages back, so checking gigabytes does not keep them
/// resident).
pub(super) fn verify_releasing(
    bytes: &[u8],
    release: &(dyn Fn(&[u8]) + Sync),
) -> Result<Vec<SectionEntry>, PackageError> {
    let len = bytes.len();
    if len < MAGIC.len() {
        return if bytes == &MAGIC[..len] && len > 0 {
            Err(truncated("the magic", MAGIC.len() as u64, len))
        } else {
            Err(PackageError::NotAPackage)
        };
    }
    if bytes[..4] != MAGIC {
        return Err(PackageError::NotAPackage);
    }
    if let Some(version) = u32_at(bytes, 4)
        && version != FORMAT_VERSION
    {
        return Err(PackageError::Version {
            path: None,
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    let (Some(count), Some(stored_crc)) = (u32_at(bytes, 8), u32_at(bytes, 12)) else {
        return Err(truncated("the header", HEADER_LEN as u64, len));
    };
    if count > MAX_SECTIONS {
        return Err(PackageError::Malformed(format!(
            "{count} sections (at most {MAX_SECTIONS})"
        )));
    }
    let table_end = HEADER_LEN + ENTRY_LEN * count as usize;
    if len < table_end {
        return Err(truncated("the section table", table_end as u64, len));
    }
    if header_crc(bytes) != stored_crc {
        return Err(PackageError::Checksum {
            section: "header".into(),
        });
    }
    let mut entries = Vec::with_capacity(count as usize);
    let mut previous_end = table_end as u64;
    let mut previous_kind = 0u32;
    for i in 0..count as usize {
        let at = HEADER_LEN + ENTRY_LEN * i;
        let field = |o: usize| u32_at(bytes, at + o).unwrap_or(u32::MAX);
        let wide = |o: usize| u64_at(bytes, at + o).unwrap_or(u64::MAX);
        let entry = SectionEntry {
            kind: field(0),
            offset: wide(8),
            length: wide(16),
            crc32: field(24),
        };
        if field(4) != 0 || field(28) != 0 {
            return Err(PackageError::Malformed(format!(
                "section entry {i}: reserved bits set"
            )));
        }
        let Some(kind) = SectionKind::from_u32(entry.kind) else {
            return Err(PackageError::Malformed(format!(
                "section entry {i}: unknown kind {}",
                entry.kind
            )));
        };
        if entry.kind <= previous_kind {
            return Err(PackageError::Malformed(format!(
                "section entry {i}: kinds not strictly ascending"
            )));
        }
        if !entry.offset.is_multiple_of(SECTION_ALIGN) || entry.offset < previous_end {
            return Err(PackageError::Malformed(format!(
                "section {}: offset {} misaligned or overlapping",
                kind.name(),
                entry.offset
            )));
        }
        let end = entry.offset.checked_add(entry.length).ok_or_else(|| {
            PackageError::Malformed(format!("section {}: length overflows", kind.name()))
        })?;
        if end > len as u64 {
            return Err(truncated(&format!("section {}", kind.name()), end, len));
        }
        if bytes[previous_end as usize..entry.offset as usize]
            .iter()
            .any(|&b| b != 0)
        {
            return Err(PackageError::Malformed(format!(
                "non-zero padding before section {}",
                kind.name()
            )));
        }
        previous_end = end;
        previous_kind = entry.kind;
        entries.push(entry);
    }
    if (len as u64) > previous_end {
        return Err(PackageError::Malformed(format!(
            "{} trailing bytes after the last section",
            len as u64 - previous_end
        )));
    }
    let bad = std::thread::scope(|scope| {
        // Every section's checksum, in parallel in chunks (gigabytes at a million buildings).
        let checks: Vec<_> = entries
            .iter()
            .map(|e| {
                let payload = &bytes[e.offset as usize..(e.offset + e.length) as usize];
                (e, payload_crc(scope, payload, release))
            })
            .collect();
        checks
            .into_iter()
            .find_map(|(e, crc)| (crc() != e.crc32).then_some(e.kind))
    });
    if let Some(kind) = bad {
        let name = SectionKind::from_u32(kind).map_or("?", SectionKind::name);
        return Err(PackageError::Checksum {
            section: name.into(),
        });
    }
    for kind in SectionKind::ALL.into_iter().filter(|k| k.required()) {
        if !entries.iter().any(|e| e.kind == kind as u32) {
            return Err(PackageError::Malformed(format!(
                "missing section {}",
                kind.name()
            )));
        }
    }
    Ok(entries)
}

/// Which sections a decode turns into values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decode {
    /// Every section.
    All,
    /// What drawing the scene needs: every section but the occluder set (the runtime draws the
    /// occluders from the GPU scene's arrays), which is left `None`, the cluster tree's meshes
    /// (drawn from the GPU scene too) and footprints ([`ClusterTree::drop_footprints`]), and
    /// the buildings' parts and tags, left empty. At a million buildings these are gigabytes
    /// of heap and seconds of decoding no frame reads; what is left of the buildings
    /// (footprints, heights, source meshes) is what camera paths need.
    Runtime,
    /// [`Decode::Runtime`] with the buildings' parts (their tags are read past without a copy):
    /// what the viewer needs, whose walking collides with the parts. At a million buildings the
    /// tags alone are 600 MB of heap.
    RuntimeWithParts,
}

/// Decodes a package from bytes (verifying it first).
pub fn decode(bytes: &[u8]) -> Result<ScenePackage, PackageError> {
    let entries = verify(bytes)?;
    decode_verified(bytes, &entries)
}

/// Decodes one section of verified bytes; `None` when the package has no such section.
pub fn decode_one<T: DeserializeOwned>(
    bytes: &[u8],
    entries: &[SectionEntry],
    kind: SectionKind,
) -> Result<Option<T>, PackageError> {
    let Some(e) = entries.iter().find(|e| e.kind == kind as u32) else {
        return Ok(None);
    };
    let err = |reason: String| PackageError::Decode {
        section: kind.name().into(),
        reason,
    };
    let payload = bytes
        .get(e.offset as usize..(e.offset + e.length) as usize)
        .ok_or_else(|| err("section outside the file".into()))?;
    let (value, rest) = postcard::take_from_bytes(payload).map_err(|e| err(e.to_string()))?;
    if !rest.is_empty() {
        return Err(err(format!("{} bytes left after the value", rest.len())));
    }
    Ok(Some(value))
}

/// One building's entry of [`SectionKind::BuildingDetails`], as it is encoded.
type DetailsEntry = (Vec<crate::BuildingPart>, crate::Tags);

/// [`DetailsEntry`] with the tags read past ([`SkippedTags`]).
type PartsOnly = (Vec<crate::BuildingPart>, SkippedTags);

/// One building's parts and tags, read alone from a package ([`read_building_details`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BuildingDetails {
    pub parts: Vec<crate::BuildingPart>,
    pub tags: crate::Tags,
}

impl BuildingDetails {
    /// The storeys above ground as the tags give them ([`crate::city::levels_tag`]).
    pub fn levels_tag(&self) -> Option<&str> {
        crate::city::levels_tag(&self.tags)
    }
}

/// Reads the parts and tags of building `index` alone from the [`SectionKind::BuildingDetails`]
/// section of verified package bytes (a mapping): the entries before it are walked without
/// allocating ([`SkippedEntry`]), nothing after it is read. postcard has no lengths to jump
/// over, so the time grows with `index` (the whole section's walk at the last building).
pub fn read_building_details(
    bytes: &[u8],
    entries: &[SectionEntry],
    index: usize,
) -> Result<BuildingDetails, PackageError> {
    let kind = SectionKind::BuildingDetails;
    let e = entries
        .iter()
        .find(|e| e.kind == kind as u32)
        .ok_or_else(|| PackageError::Malformed(format!("missing section {}", kind.name())))?;
    let payload = bytes
        .get(e.offset as usize..(e.offset + e.length) as usize)
        .ok_or_else(|| PackageError::Decode {
            section: kind.name().into(),
            reason: "section outside the file".into(),
        })?;
    let mut deserializer = postcard::Deserializer::from_bytes(payload);
    let found = serde::de::DeserializeSeed::deserialize(NthEntry(index), &mut deserializer)
        .map_err(|e| PackageError::Decode {
            section: kind.name().into(),
            reason: e.to_string(),
        })?;
    match found {
        Ok((parts, tags)) => Ok(BuildingDetails { parts, tags }),
        Err(count) => Err(PackageError::NoSuchBuilding { index, count }),
    }
}

/// Decodes entry `.0` of the details `Vec`, walking past the ones before it; `Err(len)` when
/// the `Vec` is shorter.
struct NthEntry(usize);

impl<'de> serde::de::DeserializeSeed<'de> for NthEntry {
    type Value = Result<DetailsEntry, usize>;
    fn deserialize<D: serde::Deserializer<'de>>(
        self,
        deserializer: D,
    ) -> Result<Self::Value, D::Error> {
        deserializer.deserialize_seq(self)
    }
}

impl<'de> serde::de::Visitor<'de> for NthEntry {
    type Value = Result<DetailsEntry, usize>;
    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("the buildings' details")
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
        // postcard gives the exact length up front: an index past it is answered unread.
        if let Some(len) = seq.size_hint()
            && self.0 >= len
        {
            return Ok(Err(len));
        }
        for walked in 0..self.0 {
            if seq.next_element::<SkippedEntry<'de>>()?.is_none() {
                return Ok(Err(walked));
            }
        }
        Ok(seq.next_element()?.ok_or(self.0))
    }
}

/// A building's tags read and dropped: the map's strings are borrowed from the payload as it is
/// walked, nothing is allocated.
struct SkippedTags;

impl<'de> serde::Deserialize<'de> for SkippedTags {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Walk;
        impl<'de> serde::de::Visitor<'de> for Walk {
            type Value = SkippedTags;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a map of tags")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                mut map: A,
            ) -> Result<SkippedTags, A::Error> {
                while map.next_entry::<&'de str, &'de str>()?.is_some() {}
                Ok(SkippedTags)
            }
        }
        deserializer.deserialize_map(Walk)
    }
}

/// A [`DetailsEntry`] read past without allocating: the same layout with every string
/// borrowed from the payload and every `Vec` walked element by element. postcard is not
/// self-describing (`serde::de::IgnoredAny` is refused), so the skip spells out the layout of
/// `(Vec<BuildingPart>, Tags)` (tags as a map of strings); the round-trip tests hold it to the
/// type.
#[derive(serde::Deserialize)]
struct SkippedEntry<'a>(#[serde(borrow)] SkippedSeq<SkippedPart<'a>>, SkippedTags);

/// [`crate::BuildingPart`]: source id, footprint, base, top.
#[derive(serde::Deserialize)]
#[expect(dead_code, reason = "read to walk past them, never used")]
struct SkippedPart<'a>(
    #[serde(borrow)] &'a str,
    SkippedSeq<SkippedPolygon>,
    f32,
    f32,
);

/// A `geo::Polygon<f64>`: the exterior ring, then the interior rings (a ring is a newtype of a
/// `Vec` of coordinates, transparent in postcard).
#[derive(serde::Deserialize)]
struct SkippedPolygon(SkippedSeq<(f64, f64)>, SkippedSeq<SkippedSeq<(f64, f64)>>);

/// A sequence whose elements are read as `T` and dropped.
struct SkippedSeq<T>(std::marker::PhantomData<T>);

impl<'de, T: serde::Deserialize<'de>> serde::Deserialize<'de> for SkippedSeq<T> {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Walk<T>(std::marker::PhantomData<T>);
        impl<'de, T: serde::Deserialize<'de>> serde::de::Visitor<'de> for Walk<T> {
            type Value = SkippedSeq<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a sequence")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut seq: A,
            ) -> Result<SkippedSeq<T>, A::Error> {
                while seq.next_element::<T>()?.is_some() {}
                Ok(SkippedSeq(std::marker::PhantomData))
            }
        }
        deserializer.deserialize_seq(Walk(std::marker::PhantomData))
    }
}

/// Decodes the building details section as `T` per building and gives each to `attach` with its
/// building; a section of another length than the buildings' is an inconsistent package.
fn attach_details<T: DeserializeOwned>(
    buildings: &mut [crate::Building],
    bytes: &[u8],
    entries: &[SectionEntry],
    mut attach: impl FnMut(&mut crate::Building, T),
) -> Result<(), PackageError> {
    let details: Vec<T> = required(
        decode_one(bytes, entries, SectionKind::BuildingDetails)?,
        SectionKind::BuildingDetails,
    )?;
    if details.len() != buildings.len() {
        return Err(PackageError::Inconsistent {
            sections: "building details, buildings".into(),
            reason: format!(
                "details of {} buildings for {}",
                details.len(),
                buildings.len()
            ),
        });
    }
    for (b, d) in buildings.iter_mut().zip(details) {
        attach(b, d);
    }
    Ok(())
}

fn required<T>(value: Option<T>, kind: SectionKind) -> Result<T, PackageError> {
    value.ok_or_else(|| PackageError::Malformed(format!("missing section {}", kind.name())))
}

/// Decodes the sections of bytes already [`verify`]-ed, copying the GPU scene out of them.
pub fn decode_verified(
    bytes: &[u8],
    entries: &[SectionEntry],
) -> Result<ScenePackage, PackageError> {
    let gpu_scene = gpu_scene_entry(entries).and_then(|e| {
        let payload = &bytes[e.offset as usize..(e.offset + e.length) as usize];
        GpuScene::from_payload(payload).map_err(gpu_scene_error)
    })?;
    decode_with(bytes, entries, gpu_scene, Decode::All)
}

/// [`decode_verified`] for a memory map: the GPU scene stays in the mapping.
pub(super) fn decode_mapped(
    map: &Arc<memmap2::Mmap>,
    entries: &[SectionEntry],
    what: Decode,
) -> Result<ScenePackage, PackageError> {
    let gpu_scene = gpu_scene_entry(entries).and_then(|e| {
        GpuScene::mapped(map, e.offset as usize, e.length as usize).map_err(gpu_scene_error)
    })?;
    decode_with(map, entries, gpu_scene, what)
}

fn gpu_scene_entry(entries: &[SectionEntry]) -> Result<&SectionEntry, PackageError> {
    let kind = SectionKind::GpuScene;
    entries
        .iter()
        .find(|e| e.kind == kind as u32)
        .ok_or_else(|| PackageError::Malformed(format!("missing section {}", kind.name())))
}

fn gpu_scene_error(reason: String) -> PackageError {
    PackageError::Decode {
        section: SectionKind::GpuScene.name().into(),
        reason,
    }
}

fn decode_with(
    bytes: &[u8],
    entries: &[SectionEntry],
    gpu_scene: GpuScene,
    what: Decode,
) -> Result<ScenePackage, PackageError> {
    use SectionKind as K;
    let has_occluders = entries.iter().any(|e| e.kind == K::Occluders as u32);
    if !has_occluders && !gpu_scene.view().occluders.records.is_empty() {
        return Err(PackageError::Inconsistent {
            sections: "gpu scene, occluders".into(),
            reason: "the gpu scene draws occluders the package does not have".into(),
        });
    }
    let occluder_set = |bytes, entries| match what {
        Decode::All => decode_one(bytes, entries, K::Occluders),
        Decode::Runtime | Decode::RuntimeWithParts => Ok(None),
    };
    // The three large sections decode on threads of their own in a large package (a million
    // buildings take seconds each); the result does not depend on the order.
    let (buildings, occluders, cluster_tree) = if bytes.len() < PARALLEL_DECODE_BYTES {
        (
            decode_one::<Vec<crate::Building>>(bytes, entries, K::Buildings),
            occluder_set(bytes, entries),
            decode_one(bytes, entries, K::ClusterTree),
        )
    } else {
        std::thread::scope(|scope| {
            let occluders = scope.spawn(|| occluder_set(bytes, entries));
            let cluster_tree = scope.spawn(|| decode_one(bytes, entries, K::ClusterTree));
            let buildings = decode_one(bytes, entries, K::Buildings);
            fn join<T>(r: std::thread::Result<T>) -> T {
                r.unwrap_or_else(|e| std::panic::resume_unwind(e))
            }
            (buildings, join(occluders.join()), join(cluster_tree.join()))
        })
    };
    let mut buildings = required(buildings?, K::Buildings)?;
    match what {
        Decode::Runtime => {}
        Decode::RuntimeWithParts => attach_details(
            &mut buildings,
            bytes,
            entries,
            |b, (parts, _): PartsOnly| {
                b.parts = parts;
            },
        )?,
        Decode::All => attach_details(&mut buildings, bytes, entries, |b, d: DetailsEntry| {
            (b.parts, b.tags) = d;
        })?,
    }
    let mut cluster_tree: Option<ClusterTree> = cluster_tree?;
    if let Some(tree) = &mut cluster_tree {
        // serde grows a decoded `Vec` by doubling (it caps what it reserves up front): at a
        // million buildings the nodes' slack is 150 MB.
        tree.nodes.shrink_to_fit();
    }
    match (&mut cluster_tree, what) {
        (Some(tree), Decode::All) => {
            restore_cluster_meshes(tree, &gpu_scene.view()).map_err(|reason| {
                PackageError::Inconsistent {
                    sections: "cluster tree, gpu scene".into(),
                    reason,
                }
            })?
        }
        (Some(tree), Decode::Runtime | Decode::RuntimeWithParts) => tree.drop_footprints(),
        (None, _) => {}
    }
    let pkg = ScenePackage {
        frame: required(decode_one(bytes, entries, K::Frame)?, K::Frame)?,
        buildings,
        streets: required(decode_one(bytes, entries, K::Streets)?, K::Streets)?,
        ground_areas: required(decode_one(bytes, entries, K::GroundAreas)?, K::GroundAreas)?,
        ground_surfaces: required(
            decode_one(bytes, entries, K::GroundSurfaces)?,
            K::GroundSurfaces,
        )?,
        blocks: required(decode_one(bytes, entries, K::Blocks)?, K::Blocks)?,
        quadtree: required(decode_one(bytes, entries, K::Quadtree)?, K::Quadtree)?,
        provenance: required(decode_one(bytes, entries, K::Provenance)?, K::Provenance)?,
        occluders: occluders?,
        cluster_tree,
        cluster_textures: decode_one(bytes, entries, K::ClusterTextures)?,
        timings: decode_one::<Vec<StageTiming>>(bytes, entries, K::Timings)?.unwrap_or_default(),
        gpu_scene,
        spilled: Vec::new(),
    };
    if let Err(errors) = pkg.check_sections() {
        let mut sections: Vec<&str> = errors.iter().flat_map(|(s, _)| s.split(", ")).collect();
        sections.sort_unstable();
        sections.dedup();
        return Err(PackageError::Inconsistent {
            sections: sections.join(", "),
            reason: errors
                .iter()
                .map(|(s, r)| format!("{s}: {r}"))
                .collect::<Vec<_>>()
                .join("; "),
        });
    }
    Ok(pkg)
}

/// Gives every node of `tree` its cluster mesh back from the GPU scene, which stores it once
/// (the tree section does not): the vertices and indices of the node's draw record, exactly as
/// [`crate::scene_geometry::lod_geometry`] laid them out.
fn restore_cluster_meshes(tree: &mut ClusterTree, scene: &GpuSceneView<'_>) -> Result<(), String> {
    if scene.cluster_count() != tree.nodes.len() {
        return Err(format!(
            "{} cluster records for {} nodes",
            scene.cluster_count(),
            tree.nodes.len()
        ));
    }
    let clusters = &scene.records[scene.building_count as usize..];
    for (n, (node, r)) in tree.nodes.iter_mut().zip(clusters).enumerate() {
        let base = r.base_vertex as usize;
        let first = r.first_index as usize;
        let (Some(vertices), Some(indices)) = (
            scene.vertices.get(base..base + r.vertex_count as usize),
            scene.indices.get(first..first + r.index_count as usize),
        ) else {
            return Err(format!("node {n}: its record's ranges are past the arrays"));
        };
        node.mesh = TriangleMesh {
            positions: vertices
                .iter()
                .map(|v| glam::Vec3::from_array(v.position_m))
                .collect(),
            indices: indices.to_vec(),
        };
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_payload_hashed_in_parallel_chunks_has_the_whole_payloads_crc() {
        let len = CRC_CHUNK * 2 + CRC_CHUNK / 3;
        let payload: Vec<u8> = (0..len as u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        // Every chunk is handed over once hashed: together, the whole payload once.
        let released = std::sync::Mutex::new(Vec::new());
        let release = |chunk: &[u8]| {
            let start = chunk.as_ptr() as usize - payload.as_ptr() as usize;
            released.lock().expect("lock").push((start, chunk.len()));
        };
        let crc = std::thread::scope(|scope| payload_crc(scope, &payload, &release)());
        assert_eq!(crc, crc32fast::hash(&payload));
        let mut released = released.into_inner().expect("lock");
        released.sort_unstable();
        let chunks: Vec<_> = (0..len)
            .step_by(CRC_CHUNK)
            .map(|start| (start, CRC_CHUNK.min(len - start)))
            .collect();
        assert_eq!(released, chunks);
    }
}
