//! Loading any supported input into a [`City`].
//!
//! The format is chosen by file extension, and for `.json` by content (CityJSON has
//! `"type": "CityJSON"`, GeoJSON `"type": "FeatureCollection"`). Wavefront OBJ (`.obj`)
//! names neither CRS nor up axis: [`LoadOptions::source_crs`] and [`LoadOptions::up_axis`]
//! give them.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::city::City;
use crate::report::LoadError;

mod assemble;
pub mod cityjson;
mod duplicates;
mod far_apart;
pub mod geojson;
pub mod gltf;
pub mod heights;
mod mesh_building;
pub mod obj;
pub mod osm;
mod raw_areas;

/// Options shared by the loaders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoadOptions {
    /// Height of one storey, for `building:levels` / `levels` (metres). 3 m is the OSM
    /// Simple 3D Buildings convention.
    pub level_height_m: f32,
    /// Height given to a building with no height information (metres), marked
    /// [`crate::HeightSource::Estimated`]: three storeys of [`LoadOptions::level_height_m`].
    pub default_height_m: f32,
    /// GeoJSON: a property to read the height (metres) from before the standard ones
    /// (`height`, `render_height_m`, `levels`).
    pub height_property: Option<String>,
    /// Whether to load streets (OSM `highway=*` ways) as well as buildings.
    pub load_streets: bool,
    /// The CRS of inputs that name none (OBJ), as `EPSG:NNNN` ([`parse_crs`]); `None` leaves
    /// them in a local frame. Inputs that name their own CRS keep it.
    pub source_crs: Option<String>,
    /// Which source axis points up, for inputs that do not say (OBJ).
    pub up_axis: UpAxis,
    /// OBJ: an object or group is a building when its name, a group name or a material it
    /// uses contains one of these (ASCII case-insensitive). The default `building` matches
    /// 3dfier's `Building` material (and `BuildingRoof`, `BuildingWall`, ...).
    pub obj_building_markers: Vec<String>,
}

/// The up axis of a source without one.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum UpAxis {
    /// `(x, y, z)` = (east, north, up), as 3dfier writes projected coordinates.
    #[default]
    Z,
    /// `(x, y, z)` = (east, up, south), the glTF / Blender convention: north is `-z`.
    Y,
}

impl UpAxis {
    /// Reads a `--up` value: `z` or `y` (any case).
    pub fn parse(s: &str) -> Result<UpAxis, String> {
        match s.trim().to_ascii_lowercase().as_str() {
            "z" => Ok(UpAxis::Z),
            "y" => Ok(UpAxis::Y),
            _ => Err(format!("expected z or y, got {s:?}")),
        }
    }
}

/// Checks a `--crs` value: `EPSG:NNNN` (any case) of a projected CRS in metres, returned as
/// `EPSG:NNNN`. Geographic CRSs (degrees) are refused: an OBJ model is in metres.
pub fn parse_crs(s: &str) -> Result<String, String> {
    let code = s
        .trim()
        .split_once(':')
        .filter(|(authority, _)| authority.eq_ignore_ascii_case("EPSG"))
        .and_then(|(_, code)| code.parse::<u32>().ok())
        .ok_or_else(|| format!("expected EPSG:NNNN, got {s:?}"))?;
    if matches!(code, 4326 | 4979 | 4258 | 4937 | 7912 | 4289) {
        return Err(format!(
            "EPSG:{code} is geographic (degrees); a projected CRS in metres is expected"
        ));
    }
    Ok(format!("EPSG:{code}"))
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            level_height_m: 3.0,
            default_height_m: 9.0,
            height_property: None,
            load_streets: true,
            source_crs: None,
            up_axis: UpAxis::Z,
            obj_building_markers: vec!["building".to_string()],
        }
    }
}

/// The input formats citywalk reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum InputFormat {
    OsmPbf,
    GeoJson,
    CityJson,
    Gltf,
    Obj,
}

/// Detects the format of `path` from its extension and, for `.json`, its first bytes.
pub fn detect_format(path: &Path) -> Result<InputFormat, LoadError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if name.ends_with(".osm.pbf") || name.ends_with(".pbf") {
        return Ok(InputFormat::OsmPbf);
    }
    if name.ends_with(".geojson") {
        return Ok(InputFormat::GeoJson);
    }
    if name.ends_with(".glb") || name.ends_with(".gltf") || name.ends_with(".b3dm") {
        return Ok(InputFormat::Gltf);
    }
    if name.ends_with(".obj") {
        return Ok(InputFormat::Obj);
    }
    if name.ends_with(".city.json") || name.ends_with(".cityjson") {
        return Ok(InputFormat::CityJson);
    }
    if name.ends_with(".json") {
        let head = read_head(path, 4096)?;
        let head = String::from_utf8_lossy(&head);
        if head.contains("\"CityJSON\"") {
            return Ok(InputFormat::CityJson);
        }
        if head.contains("\"FeatureCollection\"") || head.contains("\"Feature\"") {
            return Ok(InputFormat::GeoJson);
        }
        // A 3D Tiles tileset (its tiles hold glTF).
        if name == "tileset.json" || head.contains("\"geometricError\"") {
            return Ok(InputFormat::Gltf);
        }
        return Err(LoadError::Unsupported {
            path: path.to_path_buf(),
            reason: "JSON that is neither CityJSON nor a GeoJSON FeatureCollection".into(),
        });
    }
    Err(LoadError::Unsupported {
        path: path.to_path_buf(),
        reason: "unknown extension (expected .osm.pbf, .pbf, .geojson, .json, .city.json, \
                 .cityjson, .glb, .gltf, .b3dm, .obj)"
            .into(),
    })
}

/// The UTF-8 byte order mark. RFC 8259 §8.1 forbids writing it in JSON but lets a parser
/// ignore it; Windows editors and some exporters write it, and `serde_json` refuses it.
pub(crate) const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// `bytes` without a leading UTF-8 byte order mark: every JSON input (GeoJSON, CityJSON, glTF,
/// tileset, batch table) goes through this or skips the mark the same way.
pub(crate) fn without_bom(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(UTF8_BOM).unwrap_or(bytes)
}

fn read_head(path: &Path, len: usize) -> Result<Vec<u8>, LoadError> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut head = Vec::with_capacity(len);
    file.take(len as u64)
        .read_to_end(&mut head)
        .map_err(|source| LoadError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(head)
}

/// Loads one input file into a city.
pub fn load_city(path: &Path, options: &LoadOptions) -> Result<City, LoadError> {
    let city = match detect_format(path)? {
        InputFormat::OsmPbf => osm::load(path, options)?,
        InputFormat::GeoJson => geojson::load(path, options)?,
        InputFormat::CityJson => cityjson::load(path, options)?,
        InputFormat::Gltf => gltf::load(path, options)?,
        InputFormat::Obj => obj::load(path, options)?,
    };
    debug_assert!(city.report.is_balanced());
    city.report.log_items();
    Ok(city)
}

/// Loads several input files into one city, in the frame of the first. All inputs must share
/// one coordinate reference system. A file given twice, a file already read as part of an
/// earlier input, and a building repeated under one source id are kept once, each with a
/// warning ([`duplicates`]); inputs far apart are warned of ([`far_apart`]).
pub fn load_cities(paths: &[PathBuf], options: &LoadOptions) -> Result<City, LoadError> {
    let mut read = duplicates::ReadFiles::default();
    let mut skipped = Vec::new();
    let mut spans = Vec::new();
    let mut merged: Option<City> = None;
    for path in paths {
        if let Some(warning) = read.skip(path) {
            tracing::warn!("{warning}");
            skipped.push(warning);
            continue;
        }
        let format = detect_format(path)?;
        let other = load_city(path, options)?;
        read.add(path, &other.report.files);
        let start = merged.as_ref().map_or(0, |c| c.buildings.len());
        let city = match merged.as_mut() {
            None => merged.insert(other),
            Some(city) => {
                merge_into(city, other, path)?;
                city
            }
        };
        spans.push(duplicates::InputSpan {
            file: path.clone(),
            format,
            buildings: start..city.buildings.len(),
        });
    }
    let mut city = merged.ok_or_else(|| LoadError::Unsupported {
        path: PathBuf::new(),
        reason: "no input file given".into(),
    })?;
    city.report.warnings.extend(skipped);
    far_apart::warn_far_apart(&mut city, &spans);
    duplicates::drop_duplicate_buildings(&mut city, &spans);
    if city.buildings.iter().any(|b| b.mesh.is_some()) {
        // Each mesh file rested on its own lowest base; the merged city rests on the lowest.
        mesh_building::rest_on_ground(&mut city);
    }
    city.renumber();
    city.compact_buildings();
    Ok(city)
}

/// Moves `other` into `city`'s frame and appends its buildings, streets and ground areas.
fn merge_into(city: &mut City, other: City, path: &Path) -> Result<(), LoadError> {
    use glam::DVec3;
    if std::mem::discriminant(&city.frame.crs) != std::mem::discriminant(&other.frame.crs) {
        return Err(LoadError::Unsupported {
            path: path.to_path_buf(),
            reason: format!(
                "its CRS {:?} differs from the first input's {:?}",
                other.frame.crs, city.frame.crs
            ),
        });
    }
    let (from, to) = (other.frame.clone(), city.frame.clone());
    let move_xy = |x: f64, y: f64| {
        let p = to.to_local(from.to_source(DVec3::new(x, y, 0.0)));
        (p.x, p.y)
    };
    let move_z = |p: glam::Vec3| {
        let q = to.to_local(from.to_source(p.as_dvec3()));
        q.as_vec3()
    };
    use geo::MapCoordsInPlace;
    for mut b in other.buildings {
        b.footprint
            .map_coords_in_place(|c| move_xy(c.x, c.y).into());
        for part in &mut b.parts {
            part.footprint
                .map_coords_in_place(|c| move_xy(c.x, c.y).into());
        }
        if let Some(mesh) = &mut b.mesh {
            // Mesh heights are absolute in the source: base and top follow the mesh into the
            // other frame (footprint heights are above the ground and stay).
            let anchor = mesh.positions.first().copied();
            mesh.positions.iter_mut().for_each(|p| *p = move_z(*p));
            if let (Some(before), Some(after)) = (anchor, mesh.positions.first()) {
                let dz = after.z - before.z;
                b.base_m += dz;
                b.top_m += dz;
                for part in &mut b.parts {
                    part.base_m += dz;
                    part.top_m += dz;
                }
            }
        }
        city.buildings.push(b);
    }
    for mut s in other.streets {
        s.line.map_coords_in_place(|c| move_xy(c.x, c.y).into());
        city.streets.push(s);
    }
    for mut g in other.ground_areas {
        g.polygon.map_coords_in_place(|c| move_xy(c.x, c.y).into());
        city.ground_areas.push(g);
    }
    city.report.merge(other.report);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::{UpAxis, parse_crs};

    #[test]
    fn crs_values_parse_and_geographic_ones_are_refused() {
        assert_eq!(parse_crs("EPSG:28992"), Ok("EPSG:28992".into()));
        assert_eq!(parse_crs(" epsg:32631 "), Ok("EPSG:32631".into()));
        let geographic = parse_crs("EPSG:4326").unwrap_err();
        assert!(geographic.contains("geographic"), "{geographic}");
        assert!(parse_crs("28992").is_err());
        assert!(parse_crs("ESRI:102100").is_err());
        assert!(parse_crs("EPSG:x").is_err());
    }

    #[test]
    fn up_axes_parse() {
        assert_eq!(UpAxis::parse("z"), Ok(UpAxis::Z));
        assert_eq!(UpAxis::parse("Y"), Ok(UpAxis::Y));
        assert!(UpAxis::parse("x").unwrap_err().contains("z or y"));
    }
}
