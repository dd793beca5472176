//! OpenStreetMap PBF loader: buildings, building parts, streets and ground areas.
//!
//! What is read (OSM Simple 3D Buildings, <https://wiki.openstreetmap.org/wiki/Simple_3D_Buildings>):
//! - buildings: closed ways and `type=multipolygon` relations tagged `building=*` (not
//!   `building=no`);
//! - parts: the same, tagged `building:part=*` (not `no`) and not `building=*`; attached to the
//!   building whose outline contains them (see [`super::assemble`]);
//! - streets: ways tagged `highway=*` (not buildings, not `area=yes`), as polylines;
//! - ground areas: closed ways and multipolygon relations that are neither buildings nor
//!   parts and whose tags give a [`GroundClass`] ([`GroundClass::from_osm_tags`]: water,
//!   parks, squares, `landuse=*`, ...).
//!
//! Heights come from `height`, `min_height`, `building:levels`, `building:min_level`,
//! `roof:height` and `roof:levels` ([`super::heights`]).
//!
//! The file is read in three passes, so that only the nodes that are needed are kept:
//! relations (to learn which untagged ways are multipolygon members), ways, then nodes.
//! A building with a missing node or member way (cut by the extract) is rejected, as is an
//! unclosed building way or a relation whose rings cannot be joined.
//!
//! Blocks are read one by one ([`pass`]): an undecodable block is an error naming its index and
//! byte offset; a block of an unknown type is skipped with a warning saying so.
//!
//! `osmpbf` can panic on some corrupt blocks (an unknown relation member type); the passes run
//! under `catch_unwind` so that a corrupt file is a [`LoadError`], never a crash.

mod multipolygon;

use std::collections::{HashMap, HashSet};
use std::fs::File;
use std::io::BufReader;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use geo::Coord;
use osmpbf::{BlobReader, BlobType, Element, RelMemberType};

use super::LoadOptions;
use super::assemble::{
    AreaKind, RawArea, RawCity, RawPolygons, RawStreet, SourceCrs, assemble, street_width_m,
};
use super::heights::{HeightKeys, TaggedHeights};
use super::raw_areas::RawAreas;
use crate::city::{City, GroundClass, StreetClass};
use crate::report::{LoadError, LoadWarning, RejectReason};
use crate::tags::Tags;

const FORMAT: &str = "OSM PBF";

/// Loads buildings, parts and streets from an OSM PBF file.
pub fn load(path: &Path, options: &LoadOptions) -> Result<City, LoadError> {
    let raw = read(path, options)?;
    let city = assemble(path, raw, options)?;
    tracing::info!("{}: {}", path.display(), city.report);
    Ok(city)
}

/// Whether tags make an element a building, a part, a ground area, or none of them; a
/// building tag wins over the others, a part tag over a ground area's. `tags` gives the
/// element's tags afresh on every call.
fn classify<'a, I>(tags: impl Fn() -> I) -> Option<AreaKind>
where
    I: Iterator<Item = (&'a str, &'a str)>,
{
    let mut part = false;
    let mut building = false;
    for (k, v) in tags() {
        match k {
            "building" if v != "no" => building = true,
            "building:part" if v != "no" => part = true,
            _ => {}
        }
    }
    if building {
        Some(AreaKind::Building)
    } else if part {
        Some(AreaKind::Part)
    } else {
        GroundClass::from_osm_tags(|key| tags().find(|(k, _)| *k == key).map(|(_, v)| v))
            .map(AreaKind::Ground)
    }
}

/// Whether a way is a street line: tagged `highway=*`, neither a building nor a part, and
/// not an area (`area=yes`: a plaza, which is a ground area).
fn is_street_line<'a, I>(tags: impl Fn() -> I, kind: Option<AreaKind>) -> bool
where
    I: Iterator<Item = (&'a str, &'a str)>,
{
    !matches!(kind, Some(AreaKind::Building | AreaKind::Part))
        && tags().any(|(k, _)| k == "highway")
        && !tags().any(|(k, v)| k == "area" && v == "yes")
}

fn tag_map<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> Tags {
    tags.collect()
}

fn read_heights(tags: &Tags, options: &LoadOptions) -> TaggedHeights {
    TaggedHeights::read(|k| tags.get(k), &HeightKeys::osm(), options)
}

/// A multipolygon relation to assemble.
struct Relation {
    id: i64,
    kind: AreaKind,
    tags: Tags,
    /// Member ways and whether each is an inner ring.
    members: Vec<(i64, bool)>,
}

/// A tagged way (building, part, ground area, street, or both of the last two).
struct Way {
    id: i64,
    kind: Option<AreaKind>,
    street: bool,
    tags: Tags,
    refs: Vec<i64>,
}

/// Runs one pass over the file's elements, block by block. An error names the block (its
/// index and byte offset). Blocks of an unknown type are skipped, as the PBF format asks, but
/// each is returned as a message for a warning; a type one byte away from `OSMData` or
/// `OSMHeader` is a damaged block and an error (its data would be lost silently otherwise).
fn pass(path: &Path, f: &mut dyn FnMut(Element<'_>)) -> Result<Vec<String>, LoadError> {
    let malformed = |reason: String| LoadError::Malformed {
        path: path.to_path_buf(),
        format: FORMAT,
        reason,
    };
    let file = File::open(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let reader =
        BlobReader::new_seekable(BufReader::new(file)).map_err(|e| malformed(e.to_string()))?;
    let mut skipped = Vec::new();
    let result = catch_unwind(AssertUnwindSafe(|| -> Result<(), String> {
        for (k, blob) in reader.enumerate() {
            let blob = blob.map_err(|e| format!("block {k}: {e}"))?;
            let at = match blob.offset() {
                Some(offset) => format!("block {k} (at byte {})", offset.0),
                None => format!("block {k}"),
            };
            match blob.get_type() {
                BlobType::OsmHeader => {}
                BlobType::OsmData => blob
                    .to_primitiveblock()
                    .map_err(|e| format!("{at}: {e}"))?
                    .for_each_element(&mut *f),
                BlobType::Unknown(kind) if damaged_type(kind) => {
                    return Err(format!(
                        "{at}: block type {kind:?} is a damaged \"OSMData\" or \"OSMHeader\""
                    ));
                }
                BlobType::Unknown(kind) => {
                    skipped.push(format!("{at}: block of unknown type {kind:?} skipped"));
                }
            }
        }
        Ok(())
    }));
    match result {
        Ok(Ok(())) => Ok(skipped),
        Ok(Err(reason)) => Err(malformed(reason)),
        Err(_) => Err(malformed("corrupt block (the decoder gave up)".into())),
    }
}

/// Whether an unknown block type is one changed byte away from a known one.
fn damaged_type(kind: &str) -> bool {
    ["OSMData", "OSMHeader"].iter().any(|known| {
        known.len() == kind.len()
            && known
                .bytes()
                .zip(kind.bytes())
                .filter(|(a, b)| a != b)
                .count()
                == 1
    })
}

/// Reads the file into raw areas and streets in lon/lat.
fn read(path: &Path, options: &LoadOptions) -> Result<RawCity, LoadError> {
    let len = std::fs::metadata(path)
        .map_err(|source| LoadError::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    if len == 0 {
        return Err(LoadError::Malformed {
            path: path.to_path_buf(),
            format: FORMAT,
            reason: "empty file".into(),
        });
    }

    // Pass 1: multipolygon relations that are buildings, parts or ground areas. Skipped
    // blocks are told once, from this pass.
    let mut relations: Vec<Relation> = Vec::new();
    let skipped = pass(path, &mut |e| {
        if let Element::Relation(r) = e {
            let is_mp = r.tags().any(|(k, v)| k == "type" && v == "multipolygon");
            if !is_mp {
                return;
            }
            let Some(kind) = classify(|| r.tags()) else {
                return;
            };
            let members = r
                .members()
                .filter(|m| m.member_type == RelMemberType::Way)
                .map(|m| (m.member_id, m.role().is_ok_and(|role| role == "inner")))
                .collect();
            relations.push(Relation {
                id: r.id(),
                kind,
                tags: tag_map(r.tags()),
                members,
            });
        }
    })?;
    let member_ways: HashSet<i64> = relations
        .iter()
        .flat_map(|r| r.members.iter().map(|m| m.0))
        .collect();

    // Pass 2: tagged ways and member ways.
    let mut ways: Vec<Way> = Vec::new();
    let mut member_refs: HashMap<i64, Vec<i64>> = HashMap::new();
    let mut saw_any = false;
    pass(path, &mut |e| {
        saw_any = true;
        if let Element::Way(w) = e {
            let kind = classify(|| w.tags());
            let is_street = options.load_streets && is_street_line(|| w.tags(), kind);
            let is_member = member_ways.contains(&w.id());
            if kind.is_none() && !is_street && !is_member {
                return;
            }
            let refs: Vec<i64> = w.refs().collect();
            if is_member {
                member_refs.insert(w.id(), refs.clone());
            }
            if kind.is_some() || is_street {
                ways.push(Way {
                    id: w.id(),
                    kind,
                    street: is_street,
                    tags: tag_map(w.tags()),
                    refs,
                });
            }
        }
    })?;
    if !saw_any {
        return Err(LoadError::Malformed {
            path: path.to_path_buf(),
            format: FORMAT,
            reason: "no OSM data blocks".into(),
        });
    }

    // Pass 3: the nodes those ways use. PBF coordinates are integers, never NaN, so NaN marks
    // a node that is not in the file.
    const MISSING: Coord<f64> = Coord {
        x: f64::NAN,
        y: f64::NAN,
    };
    let mut nodes: HashMap<i64, Coord<f64>> = HashMap::new();
    let needed = ways
        .iter()
        .map(|w| &w.refs)
        .chain(member_refs.values())
        .flatten();
    for &n in needed {
        nodes.insert(n, MISSING);
    }
    pass(path, &mut |e| {
        let (id, lon, lat) = match e {
            Element::Node(n) => (n.id(), n.lon(), n.lat()),
            Element::DenseNode(n) => (n.id(), n.lon(), n.lat()),
            _ => return,
        };
        if let Some(c) = nodes.get_mut(&id) {
            *c = Coord { x: lon, y: lat };
        }
    })?;
    let node = |n: &i64| nodes.get(n).copied().filter(|c| !c.x.is_nan());
    let coords = |refs: &[i64]| -> Result<Vec<Coord<f64>>, RejectReason> {
        refs.iter()
            .map(|n| {
                node(n).ok_or_else(|| {
                    RejectReason::MissingGeometry(format!("node/{n} is not in the file"))
                })
            })
            .collect()
    };

    let mut areas = RawAreas::default();
    let mut streets = Vec::new();
    let mut warnings: Vec<LoadWarning> = skipped
        .into_iter()
        .map(|message| LoadWarning {
            file: path.to_path_buf(),
            source_id: String::new(),
            message,
        })
        .collect();
    for w in ways {
        let source_id = format!("way/{}", w.id);
        if w.street {
            let points: Vec<Coord<f64>> = w.refs.iter().filter_map(node).collect();
            let class = StreetClass::from_osm_highway(w.tags.get("highway").unwrap_or(""));
            streets.push(RawStreet {
                source_id: source_id.clone(),
                class,
                name: w.tags.get("name").map(str::to_string),
                points: Ok(points),
                tagged_width_m: street_width_m(|k| w.tags.get(k).map(str::to_string)),
            });
        }
        if let Some(kind) = w.kind {
            let polygons = if w.refs.len() < 2 || w.refs.first() != w.refs.last() {
                Err(RejectReason::InvalidGeometry("way is not closed".into()))
            } else {
                coords(&w.refs).map(|ring| vec![vec![ring]])
            };
            areas.push(RawArea {
                source_id,
                kind,
                polygons,
                heights: read_heights(&w.tags, options),
                tags: w.tags,
                link_ids: Vec::new(),
                part_of: None,
            });
        }
    }
    for r in relations {
        let source_id = format!("relation/{}", r.id);
        let polygons = assemble_relation(&r, &member_refs, &coords);
        let polygons = polygons.map(|(polys, dropped)| {
            if dropped > 0 {
                warnings.push(LoadWarning {
                    file: path.to_path_buf(),
                    source_id: source_id.clone(),
                    message: format!("{dropped} inner ring(s) inside no outer ring dropped"),
                });
            }
            polys
        });
        areas.push(RawArea {
            source_id,
            kind: r.kind,
            polygons,
            heights: read_heights(&r.tags, options),
            tags: r.tags,
            link_ids: Vec::new(),
            part_of: None,
        });
    }
    Ok(RawCity {
        crs: SourceCrs::Wgs84,
        areas,
        streets,
        warnings,
    })
}

/// Joins a relation's member ways into rings and groups them into polygons.
fn assemble_relation(
    r: &Relation,
    member_refs: &HashMap<i64, Vec<i64>>,
    coords: &impl Fn(&[i64]) -> Result<Vec<Coord<f64>>, RejectReason>,
) -> Result<(RawPolygons, usize), RejectReason> {
    let mut outer_ways = Vec::new();
    let mut inner_ways = Vec::new();
    for &(way, inner) in &r.members {
        let Some(refs) = member_refs.get(&way) else {
            return Err(RejectReason::MissingGeometry(format!(
                "member way/{way} is not in the file"
            )));
        };
        if inner {
            inner_ways.push(refs.clone());
        } else {
            outer_ways.push(refs.clone());
        }
    }
    if outer_ways.is_empty() {
        return Err(RejectReason::MissingGeometry(
            "multipolygon without outer member".into(),
        ));
    }
    let join = |ways| {
        multipolygon::join_rings(ways)
            .map_err(|e| RejectReason::InvalidGeometry(format!("multipolygon not assembled: {e}")))
    };
    let outers = join(outer_ways)?;
    let inners = join(inner_ways)?;
    let outers: Result<Vec<_>, _> = outers.iter().map(|r| coords(r)).collect();
    let inners: Result<Vec<_>, _> = inners.iter().map(|r| coords(r)).collect();
    Ok(multipolygon::group_polygons(outers?, inners?))
}
