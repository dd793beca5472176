//! 3D Tiles 1.1 feature identity in glTF: `EXT_mesh_features` feature ids per vertex and the
//! `EXT_structural_metadata` property tables that name them (as citywalk's own export and
//! other 3D Tiles 1.1 writers produce), the successor of b3dm's `_BATCHID` and batch table.
//!
//! A primitive's first feature-id set that reads a vertex attribute (`_FEATURE_ID_n`) and
//! points at a property table groups its triangles into features; a feature is named by the
//! table's first string property among [`name_properties`], else `table#id`. Feature-id sets
//! by texture or by implicit index are not read (the primitive stays one feature).

use ::gltf::buffer;
use serde_json::Value;

/// Property names read as a feature's source id, in order of preference: citywalk's export
/// writes `source_id`; other writers, the batch tables' id columns.
fn name_properties() -> impl Iterator<Item = &'static str> {
    std::iter::once("source_id").chain(super::ID_COLUMNS)
}

/// The feature-id attribute and property table of a primitive, if it has one.
pub fn primitive_feature_ids(extension: Option<&Value>) -> Option<(u64, usize)> {
    let sets = extension?.get("featureIds")?.as_array()?;
    sets.iter().find_map(|set| {
        let attribute = set.get("attribute")?.as_u64()?;
        let table = set.get("propertyTable")?.as_u64()? as usize;
        Some((attribute, table))
    })
}

/// The names of the features of each property table (`None` where a table has no string name
/// property or its values do not decode).
pub fn table_names(
    root: Option<&Value>,
    doc: &::gltf::Document,
    buffers: &[buffer::Data],
) -> Vec<Option<Vec<String>>> {
    let Some(tables) = root
        .and_then(|r| r.get("propertyTables"))
        .and_then(Value::as_array)
    else {
        return Vec::new();
    };
    let class_properties = |class: &str| -> Option<&serde_json::Map<String, Value>> {
        root?
            .get("schema")?
            .get("classes")?
            .get(class)?
            .get("properties")?
            .as_object()
    };
    tables
        .iter()
        .map(|table| {
            let count = table.get("count")?.as_u64()? as usize;
            let class = table.get("class")?.as_str()?;
            let schema = class_properties(class)?;
            let properties = table.get("properties")?.as_object()?;
            name_properties().find_map(|name| {
                let is_string = schema.get(name)?.get("type")?.as_str()? == "STRING";
                if !is_string {
                    return None;
                }
                strings(properties.get(name)?, count, doc, buffers)
            })
        })
        .collect()
}

/// The bytes of buffer view `index`, if it lies inside its buffer.
fn view_bytes<'a>(
    index: &Value,
    doc: &::gltf::Document,
    buffers: &'a [buffer::Data],
) -> Option<&'a [u8]> {
    let view = doc.views().nth(index.as_u64()? as usize)?;
    let data = buffers.get(view.buffer().index())?;
    let start = view.offset();
    data.get(start..start.checked_add(view.length())?)
}

/// A STRING property's `count` values (UINT32 string offsets, the default and what citywalk
/// writes; other offset types are not read).
fn strings(
    property: &Value,
    count: usize,
    doc: &::gltf::Document,
    buffers: &[buffer::Data],
) -> Option<Vec<String>> {
    let offset_type = property
        .get("stringOffsetType")
        .and_then(Value::as_str)
        .unwrap_or("UINT32");
    if offset_type != "UINT32" {
        return None;
    }
    let values = view_bytes(property.get("values")?, doc, buffers)?;
    let offsets = view_bytes(property.get("stringOffsets")?, doc, buffers)?;
    let offsets: Vec<usize> = offsets
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as usize)
        .collect();
    if offsets.len() < count + 1 {
        return None;
    }
    (0..count)
        .map(|i| {
            let bytes = values.get(offsets[i]..offsets[i + 1])?;
            Some(String::from_utf8_lossy(bytes).into_owned())
        })
        .collect()
}
