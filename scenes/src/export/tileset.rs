//! `tileset.json` (3D Tiles 1.1) over the HLOD tiles, each content written as `tiles/N.glb`.
//!
//! Bounding volumes are boxes in the local frame (the root `transform` takes them to ECEF):
//! a tile's box holds its content and its children's boxes, so every content lies inside its
//! tile's volume and every child inside its parent's, as a validator checks.

use std::path::Path;

use glam::{DMat4, DVec3};
use serde_json::{Value, json};

use super::hlod::HlodTile;
use super::{ExportError, ExportReport, Source, write_file};

/// The folder of the contents, beside `tileset.json`.
pub const TILES_DIR: &str = "tiles";

/// Margin of every bounding box (metres): f32 positions and a flat content keep a volume.
const BOX_PAD_M: f64 = 0.05;

/// A written tile: its JSON and the local bounds of everything under it.
struct Written {
    json: Value,
    bounds: (DVec3, DVec3),
}

pub(super) fn write(
    source: &Source<'_>,
    root: &HlodTile,
    transform: DMat4,
    out: &Path,
) -> Result<ExportReport, ExportError> {
    let mut report = ExportReport::default();
    let n = source.building_count();
    let Some(mut written) = write_tile(source, root, out, n, &mut report)? else {
        // Nothing to draw: an empty root over the origin.
        return write_tileset(
            source,
            json!({
                "boundingVolume": {"box": bounding_box(DVec3::ZERO, DVec3::ZERO, BOX_PAD_M)},
                "geometricError": 0.0,
                "refine": "REPLACE",
            }),
            0.0,
            transform,
            out,
            report,
        );
    };
    written.json["transform"] = json!(transform.to_cols_array());
    // The root says how it refines even without children.
    written.json["refine"] = json!("REPLACE");
    let (lo, hi) = written.bounds;
    // The error of not drawing the city at all: its size.
    let geometric_error = (hi - lo).length().max(root.geometric_error_m.into());
    write_tileset(
        source,
        written.json,
        geometric_error,
        transform,
        out,
        report,
    )
}

fn write_tileset(
    source: &Source<'_>,
    root: Value,
    geometric_error: f64,
    transform: DMat4,
    out: &Path,
    report: ExportReport,
) -> Result<ExportReport, ExportError> {
    let package = source.package;
    let mut extras = json!({
        "frame": {"crs": format!("{:?}", package.frame.crs), "origin": package.frame.origin},
        "inputs": package.provenance.inputs.iter().map(|i| json!({
            "path": i.path, "sha256": i.sha256,
        })).collect::<Vec<_>>(),
        "buildings": package.buildings.len(),
        "root_transform_is_ecef": transform != DMat4::IDENTITY,
    });
    if let Some(a) = &source.attribution {
        extras["attribution"] = json!(a);
    }
    let tileset = json!({
        "asset": {
            "version": "1.1",
            "generator": format!("citywalk {}", env!("CARGO_PKG_VERSION")),
            "extras": {"citywalk": extras},
        },
        "geometricError": geometric_error,
        "root": root,
    });
    let bytes = serde_json::to_vec_pretty(&tileset).expect("JSON values serialise");
    let path = out.join("tileset.json");
    write_file(&path, &bytes)?;
    let mut report = report;
    report.bytes += bytes.len() as u64;
    Ok(report)
}

/// Writes `tile`'s content and its children's; `None` when nothing under it has triangles.
fn write_tile(
    source: &Source<'_>,
    tile: &HlodTile,
    out: &Path,
    building_count: u32,
    report: &mut ExportReport,
) -> Result<Option<Written>, ExportError> {
    let mut children = Vec::new();
    for child in &tile.children {
        if let Some(w) = write_tile(source, child, out, building_count, report)? {
            children.push(w);
        }
    }
    let index = report.tiles;
    report.tiles += 1;
    let mut bounds: Option<(DVec3, DVec3)> = None;
    let mut grow = |(lo, hi): (DVec3, DVec3)| {
        bounds = Some(match bounds {
            Some((a, b)) => (a.min(lo), b.max(hi)),
            None => (lo, hi),
        });
    };
    let mut content = None;
    if !tile.draws.is_empty() {
        let glb = source.glb(&tile.draws);
        if glb.triangles > 0 {
            let uri = format!("{TILES_DIR}/{index}.glb");
            write_file(&out.join(&uri), &glb.bytes)?;
            report.contents += 1;
            report.triangles += glb.triangles;
            report.bytes += glb.bytes.len() as u64;
            let clusters = tile.draws.iter().filter(|&&d| d >= building_count).count() as u64;
            report.clusters_written += clusters;
            report.buildings_written += tile.draws.len() as u64 - clusters;
            grow(glb.bounds);
            content = Some(uri);
        }
    }
    for c in &children {
        grow(c.bounds);
    }
    let Some((lo, hi)) = bounds else {
        report.tiles -= 1;
        return Ok(None);
    };
    let mut json = json!({
        "boundingVolume": {"box": bounding_box(lo, hi, BOX_PAD_M)},
        "geometricError": f64::from(tile.geometric_error_m),
    });
    if let Some(uri) = content {
        json["content"] = json!({"uri": uri});
    }
    if !children.is_empty() {
        json["refine"] = json!("REPLACE");
        json["children"] = Value::Array(children.into_iter().map(|c| c.json).collect());
    }
    let pad = DVec3::splat(BOX_PAD_M);
    Ok(Some(Written {
        json,
        bounds: (lo - pad, hi + pad),
    }))
}

/// The bounds of a set of local points as a 3D Tiles `box` (centre and three half-axes),
/// grown by `pad` metres so that a flat content has a volume.
fn bounding_box(lo: DVec3, hi: DVec3, pad: f64) -> [f64; 12] {
    let c = (lo + hi) * 0.5;
    let h = ((hi - lo) * 0.5).max(DVec3::ZERO) + DVec3::splat(pad);
    [c.x, c.y, c.z, h.x, 0.0, 0.0, 0.0, h.y, 0.0, 0.0, 0.0, h.z]
}
