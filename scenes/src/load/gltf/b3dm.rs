//! Batched 3D Model (b3dm) tiles of 3D Tiles 1.0: the embedded GLB and its tables.
//!
//! Layout (3D Tiles 1.0 specification, "Batched 3D Model", "Layout" and "Header"): a 28-byte
//! little-endian header `magic "b3dm", version 1, byteLength, featureTableJSONByteLength,
//! featureTableBinaryByteLength, batchTableJSONByteLength, batchTableBinaryByteLength`, then
//! the feature table (JSON, binary), the batch table (JSON, binary) and the binary glTF to the
//! end of `byteLength`. The legacy headers of pre-1.0 tiles are refused.

use serde_json::Value;

/// Size of the b3dm header in bytes.
const HEADER_BYTES: usize = 28;

/// The parts of a b3dm tile used by the loader.
#[derive(Debug)]
pub(crate) struct B3dm<'a> {
    /// The feature table JSON (`BATCH_LENGTH`, optional `RTC_CENTER`).
    pub feature_table: Value,
    /// The batch table JSON (per-feature properties), if any.
    pub batch_table: Option<Value>,
    /// The embedded GLB.
    pub glb: &'a [u8],
}

/// Splits a b3dm tile; every length is checked against the data.
pub(crate) fn parse(bytes: &[u8]) -> Result<B3dm<'_>, String> {
    let header = bytes.get(..HEADER_BYTES).ok_or_else(|| {
        format!(
            "b3dm header needs {HEADER_BYTES} bytes, file has {}",
            bytes.len()
        )
    })?;
    if header.get(..4) != Some(b"b3dm".as_slice()) {
        return Err("no b3dm magic".into());
    }
    let word = |i: usize| -> usize {
        let mut w = [0u8; 4];
        if let Some(s) = header.get(4 * i..4 * i + 4) {
            w.copy_from_slice(s);
        }
        u32::from_le_bytes(w) as usize
    };
    let version = word(1);
    if version != 1 {
        return Err(format!("b3dm version {version} (only 1 is supported)"));
    }
    let byte_length = word(2);
    if byte_length > bytes.len() || byte_length < HEADER_BYTES {
        return Err(format!(
            "b3dm byteLength {byte_length} but the file has {} bytes",
            bytes.len()
        ));
    }
    let lengths = [word(3), word(4), word(5), word(6)];
    // Legacy headers put batchLength (a small count) where the JSON length is now, followed by
    // a GLB magic ("glTF") read as a huge number; the 1.0 spec asks readers to refuse them.
    let mut offset = HEADER_BYTES;
    let mut sections = [&bytes[..0]; 4];
    for (section, len) in sections.iter_mut().zip(lengths) {
        let end = offset
            .checked_add(len)
            .filter(|&e| e <= byte_length)
            .ok_or_else(|| "b3dm table lengths run past byteLength (legacy header?)".to_string())?;
        *section = bytes.get(offset..end).unwrap_or_default();
        offset = end;
    }
    let [ft_json, _ft_bin, bt_json, _bt_bin] = sections;
    let glb = bytes.get(offset..byte_length).unwrap_or_default();
    if !glb.starts_with(b"glTF") {
        return Err("b3dm body is not a binary glTF".into());
    }
    // Without the alignment padding after it, the GLB is exactly as long as its header says.
    let glb_length = super::glb::check_header(glb, true)?;
    let glb = glb.get(..glb_length).unwrap_or(glb);
    let json = |s: &[u8], what: &str| -> Result<Option<Value>, String> {
        let text = std::str::from_utf8(s).map_err(|e| format!("{what} is not UTF-8: {e}"))?;
        let text = text.trim_end_matches([' ', '\0']);
        if text.is_empty() {
            return Ok(None);
        }
        serde_json::from_str(text)
            .map(Some)
            .map_err(|e| format!("{what} is not JSON: {e}"))
    };
    Ok(B3dm {
        feature_table: json(ft_json, "feature table")?.unwrap_or(Value::Null),
        batch_table: json(bt_json, "batch table")?,
        glb,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tile(ft: &str, bt: &str, glb: &[u8]) -> Vec<u8> {
        let len = HEADER_BYTES + ft.len() + bt.len() + glb.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"b3dm");
        for w in [1, len, ft.len(), 0, bt.len(), 0] {
            out.extend_from_slice(&(w as u32).to_le_bytes());
        }
        out.extend_from_slice(ft.as_bytes());
        out.extend_from_slice(bt.as_bytes());
        out.extend_from_slice(glb);
        out
    }

    #[test]
    fn splits_tables_and_glb() {
        let t = tile(
            r#"{"BATCH_LENGTH":2}  "#,
            r#"{"id":["a","b"]}"#,
            &glb_header(12),
        );
        let b = parse(&t).unwrap();
        assert_eq!(b.feature_table["BATCH_LENGTH"], 2);
        assert_eq!(b.batch_table.unwrap()["id"][1], "b");
        assert_eq!(b.glb, glb_header(12));
    }

    /// A GLB header alone declaring `length` bytes.
    fn glb_header(length: u32) -> Vec<u8> {
        let mut h = b"glTF".to_vec();
        h.extend(2u32.to_le_bytes());
        h.extend(length.to_le_bytes());
        h
    }

    #[test]
    fn glb_length_is_checked_and_padding_dropped() {
        let mut padded = glb_header(12);
        padded.extend([0; 4]);
        assert_eq!(parse(&tile("{}", "", &padded)).unwrap().glb, glb_header(12));
        // More than the 8-byte alignment after the GLB, or a GLB longer than the body.
        padded.extend([0; 8]);
        assert!(parse(&tile("{}", "", &padded)).is_err());
        assert!(parse(&tile("{}", "", &glb_header(20))).is_err());
    }

    #[test]
    fn refuses_bad_headers() {
        let t = tile("{}", "", &glb_header(12));
        assert!(parse(&t[..20]).is_err());
        let mut wrong_len = t.clone();
        wrong_len[8] = 200;
        assert!(parse(&wrong_len).is_err());
        let mut bad_table = t.clone();
        bad_table[12] = 255;
        assert!(parse(&bad_table).is_err());
        let mut version = t.clone();
        version[4] = 2;
        assert!(parse(&version).is_err());
        assert!(parse(&tile("{}", "", b"nope")).is_err());
    }
}
