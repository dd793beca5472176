//! 3D Tiles 1.0 `tileset.json`: the tile tree, each tile's accumulated transform and content.
//!
//! A tile's `transform` (column-major 4×4) maps its content to its parent's frame; the root's
//! maps to ECEF (3D Tiles 1.0 specification, "Tile transforms"). Content URIs are relative to
//! the tileset file; `url` is the pre-1.0 name of `uri`. Contents that are themselves tilesets
//! (`.json`) are listed so the loader can report them, not followed.

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3};
use serde_json::Value;

use crate::frame::geodetic_to_ecef;

/// Tiles nested deeper than this are not read (a guard against absurd or hostile files).
const MAX_TILE_DEPTH: usize = 64;

/// One tile with content.
#[derive(Debug, Clone)]
pub(crate) struct TileContent {
    /// Path of the content file (resolved against the tileset's folder).
    pub path: PathBuf,
    /// The URI as written.
    pub uri: String,
    /// Content (z-up) coordinates to ECEF.
    pub to_ecef: DMat4,
}

/// A parsed tileset.
#[derive(Debug, Clone)]
pub(crate) struct Tileset {
    pub contents: Vec<TileContent>,
    /// A point at the centre of the tileset in ECEF: the root bounding volume's centre.
    pub centre_ecef: DVec3,
}

/// Whether JSON text looks like a tileset (it has an `asset` or a `root` with a
/// `geometricError`).
pub(crate) fn looks_like_tileset(v: &Value) -> bool {
    v.get("root")
        .is_some_and(|r| r.get("geometricError").is_some() || r.get("content").is_some())
}

/// Parses a tileset; `path` is the tileset file (its folder resolves content URIs).
pub(crate) fn parse(path: &Path, v: &Value) -> Result<Tileset, String> {
    let root = v.get("root").ok_or("no \"root\" tile")?;
    let mut contents = Vec::new();
    walk(root, DMat4::IDENTITY, path, 0, &mut contents)?;
    let root_transform = tile_transform(root)?;
    let centre_ecef = bounding_centre(root, root_transform)
        .unwrap_or_else(|| root_transform.transform_point3(DVec3::ZERO));
    if !centre_ecef.is_finite() {
        return Err("root bounding volume is not finite".into());
    }
    Ok(Tileset {
        contents,
        centre_ecef,
    })
}

fn walk(
    tile: &Value,
    parent: DMat4,
    tileset_file: &Path,
    depth: usize,
    out: &mut Vec<TileContent>,
) -> Result<(), String> {
    if depth > MAX_TILE_DEPTH {
        return Err(format!("tiles nested deeper than {MAX_TILE_DEPTH}"));
    }
    let to_ecef = parent * tile_transform(tile)?;
    if let Some(content) = tile.get("content") {
        let uri = content
            .get("uri")
            .or_else(|| content.get("url"))
            .and_then(Value::as_str)
            .ok_or("tile content without \"uri\"")?;
        let path =
            super::uri::resolve(tileset_file, uri).map_err(|r| format!("content {uri:?}: {r}"))?;
        out.push(TileContent {
            path,
            uri: uri.to_string(),
            to_ecef,
        });
    }
    if let Some(children) = tile.get("children") {
        let children = children.as_array().ok_or("\"children\" is not an array")?;
        for child in children {
            walk(child, to_ecef, tileset_file, depth + 1, out)?;
        }
    }
    Ok(())
}

/// The tile's own `transform`, identity when absent.
fn tile_transform(tile: &Value) -> Result<DMat4, String> {
    let Some(t) = tile.get("transform") else {
        return Ok(DMat4::IDENTITY);
    };
    let values: Vec<f64> = t
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    let cols: [f64; 16] = values
        .try_into()
        .map_err(|_| "tile \"transform\" is not 16 numbers".to_string())?;
    let m = DMat4::from_cols_array(&cols);
    if !m.is_finite() {
        return Err("tile \"transform\" is not finite".into());
    }
    Ok(m)
}

/// Centre of a tile's bounding volume in ECEF (`box` and `sphere` are in the tile's frame,
/// `region` is geodetic radians and metres).
fn bounding_centre(tile: &Value, to_ecef: DMat4) -> Option<DVec3> {
    let bv = tile.get("boundingVolume")?;
    let numbers = |key: &str| -> Option<Vec<f64>> {
        bv.get(key)?.as_array()?.iter().map(Value::as_f64).collect()
    };
    if let Some(b) = numbers("box").or_else(|| numbers("sphere")) {
        let c = DVec3::new(*b.first()?, *b.get(1)?, *b.get(2)?);
        return Some(to_ecef.transform_point3(c));
    }
    let r = numbers("region")?;
    let (w, s, e, n, lo, hi) = (
        r.first()?,
        r.get(1)?,
        r.get(2)?,
        r.get(3)?,
        r.get(4)?,
        r.get(5)?,
    );
    Some(geodetic_to_ecef(
        ((w + e) * 0.5).to_degrees(),
        ((s + n) * 0.5).to_degrees(),
        (lo + hi) * 0.5,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accumulates_transforms_and_resolves_uris() {
        let v: Value = serde_json::from_str(
            r#"{"asset":{"version":"1.0"},"geometricError":1,"root":{
                "transform":[1,0,0,0, 0,1,0,0, 0,0,1,0, 100,200,300,1],
                "boundingVolume":{"box":[1,2,3, 1,0,0, 0,1,0, 0,0,1]},"geometricError":1,
                "children":[{"content":{"uri":"tiles/a.b3dm"},"geometricError":0,
                  "transform":[1,0,0,0, 0,1,0,0, 0,0,1,0, 10,0,0,1],
                  "children":[{"content":{"url":"b.b3dm"},"geometricError":0}]}]}}"#,
        )
        .unwrap();
        assert!(looks_like_tileset(&v));
        let t = parse(Path::new("/data/set/tileset.json"), &v).unwrap();
        assert_eq!(t.centre_ecef, DVec3::new(101.0, 202.0, 303.0));
        assert_eq!(t.contents.len(), 2);
        assert_eq!(t.contents[0].path, Path::new("/data/set/tiles/a.b3dm"));
        let p = t.contents[1].to_ecef.transform_point3(DVec3::ZERO);
        assert_eq!(p, DVec3::new(110.0, 200.0, 300.0));
    }

    #[test]
    fn refuses_bad_transforms() {
        let v: Value =
            serde_json::from_str(r#"{"root":{"geometricError":1,"transform":[1,2,3]}}"#).unwrap();
        assert!(parse(Path::new("t.json"), &v).is_err());
    }

    /// Issue 14 case 2, for tileset contents: no absolute path, `..` or other scheme.
    #[test]
    fn refuses_contents_outside_the_tilesets_folder() {
        for uri in [
            "/dev/zero",
            "../a.b3dm",
            "t/../../a.b3dm",
            "https://x.invalid/a.b3dm",
        ] {
            let v = serde_json::json!({"root": {"geometricError": 1, "content": {"uri": uri}}});
            let err = parse(Path::new("/data/set/tileset.json"), &v).unwrap_err();
            assert!(err.contains(uri), "{uri}: {err}");
        }
    }
}
