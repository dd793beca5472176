//! GeoJSON loader (RFC 7946): a FeatureCollection of building footprints, building parts,
//! street lines and ground areas.
//!
//! - Polygon and MultiPolygon features are buildings, or parts when the property `kind` is
//!   `"building:part"` (as written by the OSM extracts in `shared/data/*/buildings.geojson`),
//!   or when there is no `kind` and a `building:part` property but no `building` property,
//!   or ground areas when neither `kind` nor a `building` / `building:part` property makes
//!   them a building or part and their properties, read as OSM tags, give a class
//!   ([`GroundClass::from_osm_tags`], the OSM loader's mapping: water, parks, squares, ...).
//!   A part names its building with the property `part_of` (the building's feature `id` or
//!   `id` property), else it is attached by containment like an OSM part
//!   ([`super::assemble`]).
//! - LineString and MultiLineString features with a string property `highway` are streets;
//!   other lines, points, and polygons with `highway` but no `building` / `building:part` /
//!   `kind` and no ground class (street areas without `area=yes`) are skipped, counted in one
//!   warning.
//! - Heights: [`LoadOptions::height_property`] when set, then `height`, `height_m`,
//!   `render_height_m` (read as levels when `render_height_source` says it came from levels),
//!   then `levels` / `building:levels` × level height; the base from `min_height` /
//!   `min_height_m`, else `min_level` / `building:min_level`; the default otherwise
//!   (estimated). See [`super::heights`].
//! - Coordinates are lon/lat (CRS84) unless a legacy `crs` member names a projected EPSG code
//!   (the frame is then [`crate::Frame::projected`] at the data's centre) or a local CRS (a
//!   name containing `local`, e.g. `"citywalk:local"`: metres kept as they are). A file with no
//!   `crs` whose building coordinates mostly cannot be lon/lat is read as local metres, with a
//!   warning.
//! - Source ids: the feature `id`, else the `id` property, else `osm_type/osm_id` (or
//!   `osm_id`), else `feature/<index>`. Properties become tags as strings; an object property
//!   named `tags` (raw OSM tags) is flattened into them, without overriding.
//!
//! The file is parsed by `serde_json` from a memory map of it, on every thread
//! ([`parallel`]: the features kept as slices of the map, then parsed in chunks), and streamed
//! from a buffered reader where it cannot be mapped (a pipe, say; `serde_json` parses bytes in
//! memory about 1.4× as fast as through a reader, 10.4 s against 15.0 s on a generated
//! 1M-building city) or where the parallel parse finds it out of the ordinary (the stream says
//! what is wrong and where). Either way features are converted one at a time, the document is
//! never held as a `serde_json::Value` tree. Coordinates go straight into positions (no
//! intermediate `Value`), which is why this is plain `serde_json` and not the `geojson` crate,
//! whose features carry `Value` geometry and property trees.

use std::collections::BTreeMap;
use std::fmt;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::Path;

use geo::Coord;
use serde::Deserialize;
use serde::de::{self, DeserializeSeed, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};
use serde_json::{Map, Value};

use super::LoadOptions;
use super::assemble::{
    AreaKind, RawArea, RawCity, RawPolygons, RawStreet, SourceCrs, assemble, street_width_m,
};
use super::heights::{HeightKeys, TaggedHeights};
use super::raw_areas::RawAreas;
use crate::city::{City, GroundClass, StreetClass};
use crate::report::{LoadError, LoadWarning, RejectReason};
use crate::tags::Tags;

mod parallel;

const FORMAT: &str = "GeoJSON";

/// Loads a GeoJSON FeatureCollection.
pub fn load(path: &Path, options: &LoadOptions) -> Result<City, LoadError> {
    let raw = read(path, options)?;
    let city = assemble(path, raw, options)?;
    tracing::info!("{}: {}", path.display(), city.report);
    Ok(city)
}

fn malformed(path: &Path, reason: impl Into<String>) -> LoadError {
    LoadError::Malformed {
        path: path.to_path_buf(),
        format: FORMAT,
        reason: reason.into(),
    }
}

/// Reads the file into raw areas and streets in source coordinates.
fn read(path: &Path, options: &LoadOptions) -> Result<RawCity, LoadError> {
    let file = File::open(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut sink = Sink::new(options, 0);
    let top = match crate::package::map_read_only(&file) {
        Ok(map) => {
            let bytes = map.strip_prefix(super::UTF8_BOM).unwrap_or(&map);
            let parsed = |piece: &[u8]| crate::package::release_resident(&map, piece);
            match parallel::parse(bytes, options, &parsed) {
                Some((top, parsed)) => {
                    sink = parsed;
                    top
                }
                None => parse(path, serde_json::Deserializer::from_slice(bytes), &mut sink)?,
            }
        }
        Err(_) => {
            let mut reader = BufReader::with_capacity(1 << 20, file);
            let head = reader.fill_buf().map_err(|source| LoadError::Io {
                path: path.to_path_buf(),
                source,
            })?;
            if head.starts_with(super::UTF8_BOM) {
                reader.consume(super::UTF8_BOM.len());
            }
            parse(
                path,
                serde_json::Deserializer::from_reader(reader),
                &mut sink,
            )?
        }
    };
    let Top {
        kind,
        crs,
        saw_features,
    } = top;
    match kind.as_deref() {
        Some("FeatureCollection") => {}
        Some(other) => {
            return Err(malformed(
                path,
                format!("\"type\" is {other:?}, expected \"FeatureCollection\""),
            ));
        }
        None => return Err(malformed(path, "no \"type\": not a FeatureCollection")),
    }
    if !saw_features {
        return Err(malformed(path, "FeatureCollection without \"features\""));
    }
    let mut warnings = std::mem::take(&mut sink.warnings);
    if sink.ignored > 0 {
        warnings.push(LoadWarning {
            file: path.to_path_buf(),
            source_id: "-".into(),
            message: format!(
                "{} feature(s) that are neither buildings, streets nor ground areas skipped",
                sink.ignored
            ),
        });
    }
    let crs = match crs {
        Some(value) => crs_from_member(&value).map_err(|reason| LoadError::Unsupported {
            path: path.to_path_buf(),
            reason,
        })?,
        None => {
            if mostly_not_lon_lat(&sink.areas) {
                warnings.push(LoadWarning {
                    file: path.to_path_buf(),
                    source_id: "-".into(),
                    message: "no \"crs\" and the coordinates are not longitude/latitude: read \
                              as local metres"
                        .into(),
                });
                SourceCrs::Local
            } else {
                SourceCrs::Wgs84
            }
        }
    };
    Ok(RawCity {
        crs,
        areas: sink.areas,
        streets: sink.streets,
        warnings,
    })
}

/// Parses the whole document into `sink`; returns its top-level members.
fn parse<'de, R: serde_json::de::Read<'de>>(
    path: &Path,
    mut de: serde_json::Deserializer<R>,
    sink: &mut Sink<'_>,
) -> Result<Top, LoadError> {
    let top = CollectionSeed { sink }
        .deserialize(&mut de)
        .map_err(|e| malformed(path, e.to_string()))?;
    de.end()
        .map_err(|e| malformed(path, format!("after the FeatureCollection: {e}")))?;
    Ok(top)
}

/// Whether most buildings have a coordinate outside ±180° / ±90°.
fn mostly_not_lon_lat(areas: &RawAreas) -> bool {
    let mut outside = 0usize;
    let mut total = 0usize;
    for a in areas
        .iter()
        .filter(|a| !matches!(a.kind, AreaKind::Ground(_)))
    {
        let Ok(polys) = &a.polygons else { continue };
        total += 1;
        let bad = polys
            .iter()
            .flatten()
            .flatten()
            .any(|c| c.x.abs() > 180.0 || c.y.abs() > 90.0);
        outside += usize::from(bad);
    }
    total > 0 && outside * 2 > total
}

/// The CRS named by a legacy `crs` member (`{"type": "name", "properties": {"name": ...}}`).
fn crs_from_member(value: &Value) -> Result<SourceCrs, String> {
    let name = value
        .get("properties")
        .and_then(|p| p.get("name"))
        .and_then(Value::as_str)
        .ok_or_else(|| format!("\"crs\" member without a name: {value}"))?;
    let lower = name.to_ascii_lowercase();
    if lower.contains("crs84") || lower.contains("local") {
        return Ok(if lower.contains("crs84") {
            SourceCrs::Wgs84
        } else {
            SourceCrs::Local
        });
    }
    if lower.contains("epsg") {
        return match crate::frame::epsg_code(name) {
            None => Err(format!("CRS {name:?} has no EPSG code")),
            Some(4326 | 4979) => Ok(SourceCrs::Wgs84),
            Some(4978) => Err(format!("CRS {name:?} (ECEF) is not supported for GeoJSON")),
            Some(code) => Ok(SourceCrs::Projected(format!("EPSG:{code}"))),
        };
    }
    Err(format!("unknown CRS {name:?}"))
}

/// What the top level of the document said, besides its features.
struct Top {
    kind: Option<String>,
    crs: Option<Value>,
    saw_features: bool,
}

/// Collects the converted features.
struct Sink<'a> {
    options: &'a LoadOptions,
    areas: RawAreas,
    streets: Vec<RawStreet>,
    warnings: Vec<LoadWarning>,
    /// Features that are neither areas nor streets.
    ignored: usize,
    /// Index of the next feature.
    index: usize,
}

struct CollectionSeed<'s, 'a> {
    sink: &'s mut Sink<'a>,
}

impl<'de> DeserializeSeed<'de> for CollectionSeed<'_, '_> {
    type Value = Top;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<Top, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for CollectionSeed<'_, '_> {
    type Value = Top;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a GeoJSON FeatureCollection object")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Top, A::Error> {
        let mut top = Top {
            kind: None,
            crs: None,
            saw_features: false,
        };
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "type" => {
                    let v: Value = map.next_value()?;
                    top.kind = Some(v.as_str().map_or_else(|| v.to_string(), str::to_string));
                }
                "crs" => top.crs = Some(map.next_value()?),
                "features" => {
                    if top.saw_features {
                        return Err(de::Error::duplicate_field("features"));
                    }
                    top.saw_features = true;
                    map.next_value_seed(FeaturesSeed {
                        sink: &mut *self.sink,
                    })?;
                }
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(top)
    }
}

struct FeaturesSeed<'s, 'a> {
    sink: &'s mut Sink<'a>,
}

impl<'de> DeserializeSeed<'de> for FeaturesSeed<'_, '_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for FeaturesSeed<'_, '_> {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an array of GeoJSON features")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while let Some(feature) = seq.next_element::<RawFeature>()? {
            self.sink.push(feature);
        }
        Ok(())
    }
}

/// One feature as it appears in the file; every member is optional and loosely typed so that
/// a malformed feature is a rejection, not a failed file.
#[derive(Deserialize)]
struct RawFeature {
    #[serde(default)]
    id: Option<Value>,
    #[serde(default)]
    geometry: Option<RawGeometry>,
    #[serde(default)]
    properties: Option<Value>,
}

/// A feature's geometry; anything that is not an object keeps `valid == false` (the feature is
/// then rejected, the file still loads).
#[derive(Default)]
struct RawGeometry {
    kind: Option<String>,
    coordinates: Option<Coords>,
    valid: bool,
}

impl<'de> Deserialize<'de> for RawGeometry {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<RawGeometry, D::Error> {
        d.deserialize_any(GeometryVisitor)
    }
}

struct GeometryVisitor;

impl<'de> Visitor<'de> for GeometryVisitor {
    type Value = RawGeometry;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a GeoJSON geometry object")
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<RawGeometry, A::Error> {
        let mut g = RawGeometry {
            valid: true,
            ..RawGeometry::default()
        };
        while let Some(key) = map.next_key::<String>()? {
            match key.as_str() {
                "type" => g.kind = map.next_value::<Value>()?.as_str().map(str::to_string),
                "coordinates" => g.coordinates = Some(map.next_value()?),
                _ => {
                    map.next_value::<IgnoredAny>()?;
                }
            }
        }
        Ok(g)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<RawGeometry, A::Error> {
        while seq.next_element::<IgnoredAny>()?.is_some() {}
        Ok(RawGeometry::default())
    }
    fn visit_bool<E>(self, _: bool) -> Result<RawGeometry, E> {
        Ok(RawGeometry::default())
    }
    fn visit_i64<E>(self, _: i64) -> Result<RawGeometry, E> {
        Ok(RawGeometry::default())
    }
    fn visit_u64<E>(self, _: u64) -> Result<RawGeometry, E> {
        Ok(RawGeometry::default())
    }
    fn visit_f64<E>(self, _: f64) -> Result<RawGeometry, E> {
        Ok(RawGeometry::default())
    }
    fn visit_str<E>(self, _: &str) -> Result<RawGeometry, E> {
        Ok(RawGeometry::default())
    }
}

/// GeoJSON coordinates of any nesting depth. Anything that is not an array of numbers or of
/// arrays is kept as `Invalid` (the feature is then rejected); `null` numbers are NaN.
#[derive(Debug, Clone, PartialEq)]
enum Coords {
    Num(f64),
    Pos([f64; 2]),
    List(Vec<Coords>),
    Invalid,
}

impl<'de> Deserialize<'de> for Coords {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Coords, D::Error> {
        d.deserialize_any(CoordsVisitor)
    }
}

struct CoordsVisitor;

impl<'de> Visitor<'de> for CoordsVisitor {
    type Value = Coords;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("GeoJSON coordinates")
    }
    fn visit_f64<E>(self, v: f64) -> Result<Coords, E> {
        Ok(Coords::Num(v))
    }
    fn visit_i64<E>(self, v: i64) -> Result<Coords, E> {
        Ok(Coords::Num(v as f64))
    }
    fn visit_u64<E>(self, v: u64) -> Result<Coords, E> {
        Ok(Coords::Num(v as f64))
    }
    fn visit_unit<E>(self) -> Result<Coords, E> {
        Ok(Coords::Num(f64::NAN))
    }
    fn visit_bool<E>(self, _: bool) -> Result<Coords, E> {
        Ok(Coords::Invalid)
    }
    fn visit_str<E>(self, _: &str) -> Result<Coords, E> {
        Ok(Coords::Invalid)
    }
    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Coords, A::Error> {
        while map.next_entry::<IgnoredAny, IgnoredAny>()?.is_some() {}
        Ok(Coords::Invalid)
    }
    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Coords, A::Error> {
        let Some(first) = seq.next_element::<Coords>()? else {
            return Ok(Coords::List(Vec::new()));
        };
        if let Coords::Num(x) = first {
            // A position: two or three numbers (the height is ignored).
            let mut rest = [f64::NAN; 2];
            let mut n = 1;
            let mut valid = true;
            while let Some(c) = seq.next_element::<Coords>()? {
                match c {
                    Coords::Num(v) if n < 3 => rest[n - 1] = v,
                    Coords::Num(_) => {}
                    _ => valid = false,
                }
                n += 1;
            }
            return Ok(if valid && n >= 2 {
                Coords::Pos([x, rest[0]])
            } else {
                Coords::Invalid
            });
        }
        let mut list = vec![first];
        while let Some(c) = seq.next_element::<Coords>()? {
            list.push(c);
        }
        Ok(Coords::List(list))
    }
}

fn bad_coords() -> RejectReason {
    RejectReason::InvalidGeometry("malformed coordinates".into())
}

impl Coords {
    fn position(&self) -> Result<Coord<f64>, RejectReason> {
        match self {
            Coords::Pos([x, y]) => Ok(Coord { x: *x, y: *y }),
            _ => Err(bad_coords()),
        }
    }

    fn list(&self) -> Result<&[Coords], RejectReason> {
        match self {
            Coords::List(l) => Ok(l),
            _ => Err(bad_coords()),
        }
    }

    fn line(&self) -> Result<Vec<Coord<f64>>, RejectReason> {
        self.list()?.iter().map(Coords::position).collect()
    }

    fn polygon(&self) -> Result<Vec<Vec<Coord<f64>>>, RejectReason> {
        let rings: Vec<_> = self
            .list()?
            .iter()
            .map(Coords::line)
            .collect::<Result<_, _>>()?;
        if rings.is_empty() {
            return Err(RejectReason::MissingGeometry(
                "polygon without rings".into(),
            ));
        }
        Ok(rings)
    }
}

/// A property value as a tag string; `None` for null.
fn value_string(v: &Value) -> Option<String> {
    match v {
        Value::Null => None,
        Value::String(s) => Some(s.clone()),
        other => Some(other.to_string()),
    }
}

/// The tags of a feature: its properties as strings, with an object property `tags` flattened.
fn tags_of(properties: &Map<String, Value>) -> Tags {
    let mut tags = BTreeMap::new();
    for (k, v) in properties {
        if k == "tags" && v.is_object() {
            continue;
        }
        if let Some(s) = value_string(v) {
            tags.insert(k.clone(), s);
        }
    }
    if let Some(Value::Object(nested)) = properties.get("tags") {
        for (k, v) in nested {
            if let Some(s) = value_string(v) {
                tags.entry(k.clone()).or_insert(s);
            }
        }
    }
    Tags::from(tags)
}

impl<'a> Sink<'a> {
    /// An empty sink whose next feature is the file's feature `index`.
    fn new(options: &'a LoadOptions, index: usize) -> Sink<'a> {
        Sink {
            options,
            areas: RawAreas::default(),
            streets: Vec::new(),
            warnings: Vec::new(),
            ignored: 0,
            index,
        }
    }

    /// Takes what `next`, the sink of the features after this one's, collected.
    fn append(&mut self, next: Sink<'a>) {
        self.areas.append(next.areas);
        self.streets.extend(next.streets);
        self.warnings.extend(next.warnings);
        self.ignored += next.ignored;
        self.index = next.index;
    }

    fn push(&mut self, feature: RawFeature) {
        let index = self.index;
        self.index += 1;
        let empty = Map::new();
        let properties = match &feature.properties {
            Some(Value::Object(m)) => m,
            _ => &empty,
        };
        let tags = tags_of(properties);
        let feature_id = feature.id.as_ref().and_then(value_string);
        let id_property = properties.get("id").and_then(value_string);
        let source_id = feature_id
            .clone()
            .or_else(|| id_property.clone())
            .or_else(|| {
                let osm_id = properties.get("osm_id").and_then(value_string)?;
                Some(match properties.get("osm_type").and_then(Value::as_str) {
                    Some(t) => format!("{t}/{osm_id}"),
                    None => osm_id,
                })
            })
            .unwrap_or_else(|| format!("feature/{index}"));
        let geometry_kind = feature
            .geometry
            .as_ref()
            .and_then(|g| g.kind.as_deref())
            .unwrap_or("");
        let coords = feature
            .geometry
            .as_ref()
            .and_then(|g| g.coordinates.as_ref());
        let highway = properties.get("highway").and_then(Value::as_str);
        let is_no = |v: &Value| v.is_null() || v.as_str() == Some("no");
        let part = properties.get("building:part").is_some_and(|v| !is_no(v));
        let building = properties.get("building").is_some_and(|v| !is_no(v));
        let heights = self.heights(&tags);
        // Footprint datasets often carry land-use attributes on their buildings: a polygon with
        // a height or storeys of its own is a building whatever else it is tagged with.
        let has_height = heights.top_m.is_some() || heights.top_from_levels_m.is_some();
        let ground = match properties.get("kind").and_then(Value::as_str) {
            Some("building" | "building:part") => None,
            _ if part || building || has_height => None,
            _ => GroundClass::from_osm_tags(|k| tags.get(k)),
        };
        match (geometry_kind, highway) {
            ("LineString" | "MultiLineString", Some(highway)) => {
                self.push_street(&source_id, geometry_kind, coords, highway, properties);
                return;
            }
            ("LineString" | "MultiLineString" | "Point" | "MultiPoint", _) => {
                self.ignored += 1;
                return;
            }
            // A street area (a pedestrian square) is not a building unless tagged as one.
            (_, Some(_))
                if ground.is_none()
                    && !["kind", "building", "building:part"]
                        .iter()
                        .any(|k| properties.contains_key(*k)) =>
            {
                self.ignored += 1;
                return;
            }
            _ => {}
        }
        let polygons: Result<RawPolygons, RejectReason> = match (geometry_kind, coords) {
            (_, None) if feature.geometry.is_none() => Err(RejectReason::MissingGeometry(
                "feature without geometry".into(),
            )),
            _ if feature.geometry.as_ref().is_some_and(|g| !g.valid) => Err(
                RejectReason::InvalidGeometry("geometry is not an object".into()),
            ),
            ("Polygon", Some(c)) => c.polygon().map(|p| vec![p]),
            ("MultiPolygon", Some(c)) => c.list().and_then(|polys| {
                if polys.is_empty() {
                    return Err(RejectReason::MissingGeometry("empty MultiPolygon".into()));
                }
                polys.iter().map(Coords::polygon).collect()
            }),
            ("Polygon" | "MultiPolygon", None) => Err(RejectReason::MissingGeometry(
                "geometry without coordinates".into(),
            )),
            (other, _) => Err(RejectReason::InvalidGeometry(format!(
                "unsupported geometry type {other:?}"
            ))),
        };
        let kind = match (properties.get("kind").and_then(Value::as_str), ground) {
            (Some("building:part"), _) => AreaKind::Part,
            (Some("building"), _) => AreaKind::Building,
            (_, Some(class)) => AreaKind::Ground(class),
            _ if part && !building => AreaKind::Part,
            _ => AreaKind::Building,
        };
        let part_of = properties.get("part_of").and_then(value_string);
        // Parts are never linked to and carry no tags in the model: a million-building city
        // has one and a half million parts, whose tags and ids would be held through the
        // load for nothing. A building is linked to by its source id already.
        let (tags, link_ids) = match kind {
            AreaKind::Part => (Tags::default(), Vec::new()),
            _ => (
                tags,
                feature_id
                    .into_iter()
                    .chain(id_property)
                    .filter(|id| *id != source_id)
                    .collect(),
            ),
        };
        self.areas.push(RawArea {
            source_id,
            kind,
            polygons,
            tags,
            heights,
            link_ids,
            part_of,
        });
    }

    fn heights(&self, tags: &Tags) -> TaggedHeights {
        let mut top = Vec::with_capacity(4);
        if let Some(p) = &self.options.height_property {
            top.push(p.as_str());
        }
        top.extend(["height", "height_m", "render_height_m"]);
        let keys = HeightKeys {
            top,
            base: vec!["min_height", "min_height_m"],
            levels: vec!["levels", "building:levels"],
            min_levels: vec!["min_level", "building:min_level"],
            roof_height: vec!["roof:height"],
            roof_levels: vec!["roof:levels"],
        };
        let render_from_levels = tags
            .get("render_height_source")
            .is_some_and(|s| s.starts_with("levels"));
        TaggedHeights::read(
            |k| {
                if k == "render_height_m" && render_from_levels {
                    return None;
                }
                tags.get(k)
            },
            &keys,
            self.options,
        )
    }

    fn push_street(
        &mut self,
        source_id: &str,
        geometry_kind: &str,
        coords: Option<&Coords>,
        highway: &str,
        properties: &Map<String, Value>,
    ) {
        let lines: Result<Vec<Vec<Coord<f64>>>, RejectReason> = match (geometry_kind, coords) {
            ("LineString", Some(c)) => c.line().map(|l| vec![l]),
            ("MultiLineString", Some(c)) => c
                .list()
                .and_then(|ls| ls.iter().map(Coords::line).collect()),
            _ => Err(bad_coords()),
        };
        let lines: Vec<Result<Vec<Coord<f64>>, RejectReason>> = match lines {
            Ok(lines) => lines.into_iter().map(Ok).collect(),
            // Rejected in the assembly, with the streets' count.
            Err(reason) => vec![Err(reason)],
        };
        let single = lines.len() == 1;
        let tagged_width_m = street_width_m(|k| match properties.get(k)? {
            Value::String(v) => Some(v.clone()),
            Value::Number(n) => Some(n.to_string()),
            _ => None,
        });
        let name = properties
            .get("name")
            .and_then(Value::as_str)
            .map(str::to_string);
        for (k, points) in lines.into_iter().enumerate() {
            self.streets.push(RawStreet {
                source_id: if single {
                    source_id.to_string()
                } else {
                    format!("{source_id}#{k}")
                },
                class: StreetClass::from_osm_highway(highway),
                name: name.clone(),
                points,
                tagged_width_m,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crs_names() {
        let crs = |name: &str| {
            crs_from_member(&serde_json::json!({"type": "name", "properties": {"name": name}}))
        };
        assert_eq!(crs("urn:ogc:def:crs:OGC:1.3:CRS84"), Ok(SourceCrs::Wgs84));
        assert_eq!(crs("EPSG:4326"), Ok(SourceCrs::Wgs84));
        assert_eq!(
            crs("urn:ogc:def:crs:EPSG::28992"),
            Ok(SourceCrs::Projected("EPSG:28992".into()))
        );
        assert_eq!(crs("citywalk:local"), Ok(SourceCrs::Local));
        assert!(crs("urn:ogc:def:crs:EPSG::").is_err());
        assert!(crs("mystery").is_err());
    }

    #[test]
    fn coordinates_of_any_depth() {
        let c: Coords = serde_json::from_str("[[[0, 0], [1, 0.5, 9], [1, 1]]]").unwrap();
        let rings = c.polygon().unwrap();
        assert_eq!(rings[0][1], Coord { x: 1.0, y: 0.5 });
        let c: Coords = serde_json::from_str("[[[0, null], [1, 0], [1, 1]]]").unwrap();
        assert!(c.polygon().unwrap()[0][0].y.is_nan());
        let c: Coords = serde_json::from_str("[[[0, \"a\"], [1, 0], [1, 1]]]").unwrap();
        assert!(c.polygon().is_err());
        let c: Coords = serde_json::from_str("[[0, [1]]]").unwrap();
        assert!(c.polygon().is_err());
    }

    #[test]
    fn nested_tags_are_flattened_without_override() {
        let props: Map<String, Value> = serde_json::from_str(
            r#"{"height_m": 7.5, "levels": null, "tags": {"height": "7.5 m", "height_m": "x"}}"#,
        )
        .unwrap();
        let tags = tags_of(&props);
        assert_eq!(tags.get("height_m"), Some("7.5"));
        assert_eq!(tags.get("height"), Some("7.5 m"));
        assert!(!tags.contains_key("levels") && !tags.contains_key("tags"));
    }
}
