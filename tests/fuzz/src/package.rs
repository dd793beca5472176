//! The scene-package target: [`ScenePackage::from_bytes`], then
//! [`ScenePackage::check_invariants`] on what it accepts, and the decoding of its cluster
//! textures' PNGs (pages of at most 256 texels on a side: a larger page is a larger, bounded,
//! allocation, 8192² at most, which only slows the fuzzer).
//!
//! A package has a CRC-32 over its header and one per section, so nearly every mutation of a
//! real package would stop at the checksum test and the decoders behind it would never see
//! a mutated byte. The target therefore reads each input twice: as it is (the checksum and
//! layout checks), and with its checksums recomputed ([`with_checksums`]), which lets the
//! mutation through to the section decoders and the cross-section checks. Both must refuse
//! bad input with an error, never a panic.
//!
//! The layout used here is the one documented in `citywalk_scenes::package::format`:
//! a 16-byte header (magic, version, section count, header CRC-32), then 32-byte entries
//! (kind, flags, offset, length, payload CRC-32, reserved).

use citywalk_scenes::cluster_texture::atlas::AtlasView;
use citywalk_scenes::cluster_texture::tables::{MeshArrays, TextureTables};
use citywalk_scenes::package::{MAGIC, ScenePackage};

const HEADER_LEN: usize = 16;
const ENTRY_LEN: usize = 32;
/// Offset of an entry's payload checksum within the entry.
const ENTRY_CRC: usize = 24;

/// `data` as a package, as it is and with its checksums made right.
pub fn package(data: &[u8]) {
    read(data);
    if let Some(fixed) = with_checksums(data) {
        read(&fixed);
    }
}

fn read(bytes: &[u8]) {
    let Ok(package) = ScenePackage::from_bytes(bytes) else {
        return;
    };
    // Decoded sections may disagree (that is what the checker is for); it must say so, not
    // panic. Its verdict is not judged here: a package with recomputed checksums may be
    // inconsistent.
    let _verdict = package.check_invariants();
    // The runtime's tables of a textured scene, built from the layout and the GPU scene's
    // meshes as a load does: a damaged layout leaves clusters untextured, never a panic.
    if let (Some(textures), Some(tree)) = (&package.cluster_textures, &package.cluster_tree) {
        let view = package.gpu_scene.view();
        let _tables = TextureTables::build(
            &textures.layout,
            MeshArrays {
                building_count: view.building_count,
                node_count: tree.nodes.len() as u32,
                records: view.records,
                vertices: view.vertices,
                indices: view.indices,
            },
        );
    }
    if let Some(textures) = &package.cluster_textures
        && textures.layout.page_px <= 256
    {
        for page in 0..textures.images.len() {
            for view in AtlasView::ALL {
                let _image = textures.decode(page, view);
            }
        }
    }
}

/// `data` with every section checksum whose entry lies inside the file, and then the header
/// checksum, recomputed; `None` when `data` has no package header and section table to fix.
pub fn with_checksums(data: &[u8]) -> Option<Vec<u8>> {
    if data.len() < HEADER_LEN || data[..4] != MAGIC {
        return None;
    }
    let count = usize::try_from(u32_at(data, 8)?).ok()?;
    let table_end = count.checked_mul(ENTRY_LEN)?.checked_add(HEADER_LEN)?;
    if table_end > data.len() {
        return None;
    }
    let mut fixed = data.to_vec();
    for entry in (HEADER_LEN..table_end).step_by(ENTRY_LEN) {
        let (Some(offset), Some(length)) = (u64_at(data, entry + 8), u64_at(data, entry + 16))
        else {
            continue;
        };
        let payload = usize::try_from(offset)
            .ok()
            .zip(usize::try_from(length).ok())
            .and_then(|(o, l)| data.get(o..o.checked_add(l)?));
        if let Some(payload) = payload {
            let crc = crc32fast::hash(payload).to_le_bytes();
            fixed[entry + ENTRY_CRC..entry + ENTRY_CRC + 4].copy_from_slice(&crc);
        }
    }
    let mut header = crc32fast::Hasher::new();
    header.update(&fixed[..12]);
    header.update(&fixed[HEADER_LEN..table_end]);
    fixed[12..16].copy_from_slice(&header.finalize().to_le_bytes());
    Some(fixed)
}

fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
}

fn u64_at(bytes: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(bytes.get(at..at + 8)?.try_into().ok()?))
}
