//! The binary glTF (GLB) container header and the glTF `asset.version`.
//!
//! GLB layout (glTF 2.0 §4.4.3 "Header"): `magic "glTF", version 2, length`, where `length` is
//! the whole GLB in bytes. The `gltf` crate only checks that the file is not shorter than
//! `length`; a file longer than its header says, or a header shorter than itself, is a damaged
//! or concatenated file and is refused here. A GLB inside a b3dm may be followed by up to 7
//! padding bytes: 3D Tiles 1.0 ("Padding") aligns the tile's `byteLength` to 8.

/// Size of the GLB header in bytes (magic, version, length).
const HEADER_BYTES: usize = 12;

/// Checks the GLB header of `bytes` (which start with `glTF`) and returns the GLB's length.
/// `in_b3dm`: the GLB is the body of a b3dm tile and may be followed by alignment padding.
pub(crate) fn check_header(bytes: &[u8], in_b3dm: bool) -> Result<usize, String> {
    let word = |i: usize| {
        bytes
            .get(4 * i..4 * i + 4)
            .and_then(|w| <[u8; 4]>::try_from(w).ok())
            .map(u32::from_le_bytes)
    };
    let (Some(version), Some(length)) = (word(1), word(2)) else {
        return Err(format!(
            "GLB header needs {HEADER_BYTES} bytes, the file has {}",
            bytes.len()
        ));
    };
    if version != 2 {
        return Err(format!("GLB container version {version} (only 2 is read)"));
    }
    let length = length as usize;
    // `gltf` subtracts the header's size from `length` unchecked (found by fuzzing).
    if length < HEADER_BYTES {
        return Err(format!(
            "GLB header declares a length of {length} bytes, less than the header's \
             {HEADER_BYTES}"
        ));
    }
    let padding = if in_b3dm { 7 } else { 0 };
    if length > bytes.len() || bytes.len() - length > padding {
        let what = if in_b3dm { "the b3dm body" } else { "the file" };
        return Err(format!(
            "GLB header length {length} but {what} has {} bytes",
            bytes.len()
        ));
    }
    Ok(length)
}

/// Checks the glTF `asset.version` (`"major.minor"`, glTF 2.0 §3.2 "Asset"): only major
/// version 2 is read; a reader must refuse a major version it does not know.
pub(crate) fn check_asset_version(version: &str) -> Result<(), String> {
    let major = version.split_once('.').map(|(major, _)| major);
    match major {
        Some("2") => Ok(()),
        _ => Err(format!(
            "glTF asset.version {version:?}: only glTF 2.x is read"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(version: u32, length: u32, total: usize) -> Vec<u8> {
        let mut b = b"glTF".to_vec();
        b.extend(version.to_le_bytes());
        b.extend(length.to_le_bytes());
        b.resize(total, 0);
        b
    }

    #[test]
    fn length_must_match_the_file() {
        assert!(check_header(&header(2, 40, 40), false).is_ok());
        assert!(check_header(&header(2, 36, 40), false).is_err());
        assert!(check_header(&header(2, 44, 40), false).is_err());
        assert!(check_header(&header(2, 4, 40), false).is_err());
        assert!(check_header(&header(1, 40, 40), false).is_err());
        assert!(check_header(&b"glTF\x02\0"[..], false).is_err());
        // Inside a b3dm, up to 7 bytes of alignment padding may follow.
        assert!(check_header(&header(2, 36, 40), true).is_ok());
        assert!(check_header(&header(2, 32, 40), true).is_err());
    }

    #[test]
    fn only_major_version_2() {
        assert!(check_asset_version("2.0").is_ok());
        assert!(check_asset_version("2.1").is_ok());
        for bad in ["3.0", "1.0", "20.0", "2", "", "two"] {
            assert!(check_asset_version(bad).is_err(), "{bad}");
        }
    }
}
