//! Bounds-checked reading of glTF accessors (glTF 2.0 specification §3.6 "Buffers, buffer
//! views and accessors"): every offset, stride and count is checked against the buffer data,
//! so truncated or lying files give an error, never a panic.

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::{Accessor, buffer};

/// Reads an accessor's components as f64, `count × dims` values, applying the normalisation of
/// normalised integer types. Fails on sparse accessors, accessors without a buffer view, and
/// any range outside the data.
pub(crate) fn read_f64(
    accessor: &Accessor<'_>,
    buffers: &[buffer::Data],
    expected: Dimensions,
) -> Result<Vec<f64>, String> {
    let what = format!("accessor {}", accessor.index());
    if accessor.dimensions() != expected {
        return Err(format!(
            "{what} has type {:?}, expected {expected:?}",
            accessor.dimensions()
        ));
    }
    if accessor.sparse().is_some() {
        return Err(format!("{what} is sparse (not supported)"));
    }
    let view = accessor
        .view()
        .ok_or_else(|| format!("{what} has no buffer view"))?;
    let data = buffers
        .get(view.buffer().index())
        .ok_or_else(|| format!("{what}: buffer {} missing", view.buffer().index()))?;
    let view_end = view
        .offset()
        .checked_add(view.length())
        .filter(|&e| e <= data.len())
        .ok_or_else(|| {
            format!(
                "{what}: buffer view {} ({}+{} bytes) runs past its buffer ({} bytes)",
                view.index(),
                view.offset(),
                view.length(),
                data.len()
            )
        })?;
    let view_bytes = data.get(view.offset()..view_end).unwrap_or_default();
    let component = accessor.data_type().size();
    let dims = expected.multiplicity();
    let element = component * dims;
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(format!(
            "{what}: stride {stride} below element size {element}"
        ));
    }
    let count = accessor.count();
    if count == 0 {
        return Ok(Vec::new());
    }
    let needed = (count - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(element))
        .and_then(|n| n.checked_add(accessor.offset()))
        .filter(|&n| n <= view_bytes.len())
        .ok_or_else(|| {
            format!(
                "{what}: {count} elements at offset {} stride {stride} run past its view ({} \
                 bytes)",
                accessor.offset(),
                view_bytes.len()
            )
        })?;
    let bytes = view_bytes
        .get(accessor.offset()..needed)
        .unwrap_or_default();
    let normalized = accessor.normalized();
    let mut out = Vec::with_capacity(count * dims);
    for e in 0..count {
        for c in 0..dims {
            let at = e * stride + c * component;
            let raw = bytes
                .get(at..at + component)
                .ok_or_else(|| format!("{what}: element {e} out of range"))?;
            out.push(decode(raw, accessor.data_type(), normalized));
        }
    }
    Ok(out)
}

/// One little-endian component.
fn decode(raw: &[u8], ty: DataType, normalized: bool) -> f64 {
    let mut b = [0u8; 4];
    let n = raw.len().min(4);
    b[..n].copy_from_slice(&raw[..n]);
    match ty {
        DataType::I8 => {
            let v = f64::from(b[0] as i8);
            if normalized { (v / 127.0).max(-1.0) } else { v }
        }
        DataType::U8 => {
            let v = f64::from(b[0]);
            if normalized { v / 255.0 } else { v }
        }
        DataType::I16 => {
            let v = f64::from(i16::from_le_bytes([b[0], b[1]]));
            if normalized {
                (v / 32767.0).max(-1.0)
            } else {
                v
            }
        }
        DataType::U16 => {
            let v = f64::from(u16::from_le_bytes([b[0], b[1]]));
            if normalized { v / 65535.0 } else { v }
        }
        DataType::U32 => f64::from(u32::from_le_bytes(b)),
        DataType::F32 => f64::from(f32::from_le_bytes(b)),
    }
}

/// Reads an index or id accessor as non-negative integers; fails on fractional, negative or
/// non-finite values.
pub(crate) fn read_u32(
    accessor: &Accessor<'_>,
    buffers: &[buffer::Data],
) -> Result<Vec<u32>, String> {
    let values = read_f64(accessor, buffers, Dimensions::Scalar)?;
    values
        .into_iter()
        .map(|v| {
            if v.is_finite() && v >= 0.0 && v <= f64::from(u32::MAX) && v.fract() == 0.0 {
                Ok(v as u32)
            } else {
                Err(format!(
                    "accessor {}: {v} is not an index",
                    accessor.index()
                ))
            }
        })
        .collect()
}
