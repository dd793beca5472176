//! From raw 2.5D areas (OSM ways and relations, GeoJSON features) to a [`City`]: the part of the
//! OSM and GeoJSON loaders that does not depend on the file format.
//!
//! 1. The frame is centred on the bounding box of the buildings' source coordinates, after
//!    the outliers far from the median of the buildings are rejected ([`make_frame`]).
//! 2. Every area is projected, cleaned ([`crate::validate::clean_footprint`]) and given
//!    heights ([`super::heights`], checked with [`crate::validate::check_heights`]); a bad
//!    building is a [`Rejection`], a bad part a [`LoadWarning`] (parts are not buildings).
//! 3. Parts are attached to buildings following the OSM Simple 3D Buildings rules
//!    (<https://wiki.openstreetmap.org/wiki/Simple_3D_Buildings>, "Building outlines and
//!    parts"): a part belongs to the building whose outline contains it; where a building has
//!    parts, they replace its outline for the 3D shape (the building keeps its outline as
//!    `footprint`, its `parts` are the part areas). Attachment is by an explicit link
//!    (`part_of`) when given, else by containment of the part's interior point, searched in an
//!    R*-tree of the buildings' bounding boxes; among nested outlines the smallest wins.
//! 4. A part with no building (an *orphan*, typically one whose building outline was cut off
//!    by the extract) is dropped with a warning. Loading it as a building of its own would
//!    either unbalance the report (`loaded + rejected = found`) or make `buildings_found`
//!    count parts, unlike every OSM tool (the data folders' READMEs count buildings and parts
//!    apart), so the report stays as the source counts it: the part is in `parts_found` only.
//! 5. A part with no height of its own inherits its building's heights (the building's tags
//!    describe the whole building when the part says nothing).
//! 6. Ground areas (water, parks, squares: [`AreaKind::Ground`]) are projected and cleaned like
//!    footprints, without heights; one that fails, or lies beyond the local range, is a
//!    [`Rejection`] in the report's ground-area list. They take no part in placing the frame.

use std::collections::HashMap;
use std::path::Path;

use geo::{Area, BoundingRect, Coord, InteriorPoint, Intersects, LineString, MultiPolygon};
use glam::DVec3;
use rayon::prelude::*;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{AABB, RTree};

use super::LoadOptions;
use super::heights::{ResolvedHeights, TaggedHeights, parse_length_m};
use super::raw_areas::RawAreas;
use crate::city::{
    Building, BuildingId, BuildingPart, City, GroundArea, GroundClass, HeightSource, Street,
    StreetClass,
};
use crate::frame::Frame;
use crate::report::{LoadError, LoadReport, LoadWarning, RejectReason, Rejection};
use crate::tags::Tags;
use crate::validate::{CleanFootprint, MAX_LOCAL_COORDINATE_M, check_heights, clean_footprint};

/// Polygons of rings (outer ring first, then holes), in source coordinates.
pub(crate) type RawPolygons = Vec<Vec<Vec<Coord<f64>>>>;

/// Whether an area is a building, a `building:part` or a ground area.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum AreaKind {
    Building,
    Part,
    Ground(GroundClass),
}

/// One building, part or ground area as read from the source, before projection and
/// validation.
#[derive(Debug, Clone)]
pub(crate) struct RawArea {
    pub source_id: String,
    pub kind: AreaKind,
    /// The geometry, or why it could not be read (missing nodes, unassembled rings).
    pub polygons: Result<RawPolygons, RejectReason>,
    /// Its tags once its heights are read from them; a part's may be left empty (the model's
    /// parts carry none).
    pub tags: Tags,
    pub heights: TaggedHeights,
    /// Further names by which a part may link to this building (`part_of`), besides its
    /// source id.
    pub link_ids: Vec<String>,
    /// The building this part names explicitly, if any.
    pub part_of: Option<String>,
}

/// One street as read from the source.
#[derive(Debug, Clone)]
pub(crate) struct RawStreet {
    pub source_id: String,
    pub class: StreetClass,
    pub name: Option<String>,
    /// The line, or why it could not be read.
    pub points: Result<Vec<Coord<f64>>, RejectReason>,
    /// [`street_width_m`] of its tags.
    pub tagged_width_m: Option<f32>,
}

/// A lane's width when a street tags `lanes` but no `width` (metres; urban lanes are 3.0–3.5 m).
const LANE_WIDTH_M: f64 = 3.25;
/// Widths beyond this are not a street's (a typo, or a unit lost): the class default is used.
const MAX_STREET_WIDTH_M: f64 = 150.0;

/// A street's width from OSM-style tags (also GeoJSON properties): `width` as a length
/// (see [`parse_length_m`]), else `lanes` × [`LANE_WIDTH_M`]; `None` when neither gives a
/// positive width below [`MAX_STREET_WIDTH_M`].
pub(crate) fn street_width_m(tag: impl Fn(&str) -> Option<String>) -> Option<f32> {
    let plausible = |w: f64| (w > 0.0 && w <= MAX_STREET_WIDTH_M).then_some(w as f32);
    tag("width")
        .and_then(|w| parse_length_m(&w))
        .and_then(plausible)
        .or_else(|| {
            let lanes = tag("lanes")?.trim().parse::<f64>().ok()?;
            plausible(lanes.round() * LANE_WIDTH_M)
        })
}

/// The CRS of the source coordinates.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum SourceCrs {
    /// Longitude / latitude in degrees.
    Wgs84,
    /// Projected metres, with the CRS's name; the frame's origin is the data's centre.
    Projected(String),
    /// Already local metres: the frame is [`Frame::local`] and coordinates are kept.
    Local,
}

/// Everything a format reader hands over.
#[derive(Debug)]
pub(crate) struct RawCity {
    pub crs: SourceCrs,
    pub areas: RawAreas,
    pub streets: Vec<RawStreet>,
    pub warnings: Vec<LoadWarning>,
}

/// A validated area in the local frame.
struct Area2 {
    source_id: String,
    footprint: MultiPolygon<f64>,
    heights: ResolvedHeights,
    has_own_heights: bool,
    tags: Tags,
    part_of: Option<String>,
}

/// A validated part waiting for its building.
struct ValidPart {
    source_id: String,
    footprint: MultiPolygon<f64>,
    heights: ResolvedHeights,
    has_own_heights: bool,
    part_of: Option<String>,
}

/// Builds the city from what a reader found in `path`.
pub(crate) fn assemble(
    path: &Path,
    raw: RawCity,
    options: &LoadOptions,
) -> Result<City, LoadError> {
    let RawCity {
        crs,
        areas,
        streets,
        warnings,
    } = raw;
    let mut report = LoadReport {
        files: vec![path.to_path_buf()],
        warnings,
        ..LoadReport::default()
    };
    let Some((frame, outliers)) = make_frame(&crs, &areas) else {
        let found = areas
            .iter()
            .filter(|a| a.kind == AreaKind::Building)
            .count();
        let first = if areas.iter().all(|a| matches!(a.kind, AreaKind::Ground(_))) {
            "the file has no building or building:part"
        } else {
            "no building or part has a usable coordinate"
        };
        // The warnings (a skipped block, say) may tell why.
        report.log_items();
        return Err(LoadError::NothingLoaded {
            path: path.to_path_buf(),
            found,
            first: first.into(),
        });
    };
    let project = |c: Coord<f64>| -> Result<Coord<f64>, RejectReason> {
        if !(c.x.is_finite() && c.y.is_finite()) {
            return Err(RejectReason::NonFiniteCoordinate);
        }
        if crs == SourceCrs::Wgs84 && !(c.x.abs() <= 180.0 && c.y.abs() <= 90.0) {
            return Err(RejectReason::CoordinateOutOfRange(format!(
                "lon/lat ({}, {}) outside ±180°/±90°",
                c.x, c.y
            )));
        }
        let p = frame.to_local(DVec3::new(c.x, c.y, 0.0));
        Ok(Coord { x: p.x, y: p.y })
    };

    // Validate every area; buildings and ground areas that fail are rejected, parts that fail
    // are dropped.
    // Sized once: grown by doubling, a million buildings' areas would be copied into buffers
    // of up to twice their size while the raw areas are still held.
    let building_count = areas
        .iter()
        .filter(|a| a.kind == AreaKind::Building)
        .count();
    let part_count = areas.iter().filter(|a| a.kind == AreaKind::Part).count();
    // Buildings are made in their final form as they are validated (their parts attached
    // below), so that no second array of every building is made from a first.
    let mut buildings: Vec<Building> = Vec::with_capacity(building_count);
    let mut own_heights: Vec<ResolvedHeights> = Vec::with_capacity(building_count);
    let mut parts: Vec<ValidPart> = Vec::with_capacity(part_count);
    let mut ground_areas: Vec<GroundArea> = Vec::new();
    let mut link: HashMap<String, usize> = HashMap::new();
    let mut outliers = outliers.into_iter();
    // Chunk by chunk, so that a chunk's raw areas are freed as its areas are validated.
    for mut chunk in areas.into_chunks() {
        // Projecting and cleaning an area's polygons needs no other area and is most of this
        // assembly's work: done on every thread, in input order (the same city on any number).
        let chunk_outliers: Vec<_> = outliers.by_ref().take(chunk.len()).collect();
        let cleaned: Vec<Result<CleanFootprint, RejectReason>> = chunk
            .par_iter_mut()
            .zip(chunk_outliers)
            .map(|(area, outlier)| match outlier {
                Some(reason) => Err(reason),
                None => std::mem::replace(&mut area.polygons, Ok(Vec::new()))
                    .and_then(|p| clean_polygons(p, &project)),
            })
            .collect();
        for (mut area, cleaned) in chunk.into_iter().zip(cleaned) {
            if let AreaKind::Ground(class) = area.kind {
                report.ground_areas_found += 1;
                match cleaned {
                    Ok(clean) => {
                        for message in clean.repairs {
                            report.warnings.push(LoadWarning {
                                file: path.to_path_buf(),
                                source_id: area.source_id.clone(),
                                message,
                            });
                        }
                        ground_areas.push(GroundArea {
                            source_id: area.source_id,
                            class,
                            polygon: clean.footprint,
                        });
                    }
                    Err(reason) => report.ground_areas_rejected.push(Rejection {
                        file: path.to_path_buf(),
                        source_id: area.source_id,
                        reason,
                    }),
                }
                continue;
            }
            let is_building = area.kind == AreaKind::Building;
            if is_building {
                report.buildings_found += 1;
            } else {
                report.parts_found += 1;
            }
            for bad in &area.heights.unparsed {
                report.warnings.push(LoadWarning {
                    file: path.to_path_buf(),
                    source_id: area.source_id.clone(),
                    message: format!("unparseable height value {bad} ignored"),
                });
            }
            let ids = std::mem::take(&mut area.link_ids);
            let validated = validate_area(area, cleaned, options);
            match validated {
                Ok((valid, repairs)) => {
                    for r in repairs {
                        report.warnings.push(LoadWarning {
                            file: path.to_path_buf(),
                            source_id: valid.source_id.clone(),
                            message: r,
                        });
                    }
                    if is_building {
                        let index = buildings.len();
                        link.entry(valid.source_id.clone()).or_insert(index);
                        for id in ids {
                            link.entry(id).or_insert(index);
                        }
                        own_heights.push(valid.heights);
                        buildings.push(valid.into_building());
                    } else {
                        parts.push(valid.into_part());
                    }
                }
                Err((source_id, reason)) => {
                    if is_building {
                        report.rejected.push(Rejection {
                            file: path.to_path_buf(),
                            source_id,
                            reason,
                        });
                    } else {
                        report.warnings.push(LoadWarning {
                            file: path.to_path_buf(),
                            source_id,
                            message: format!("building:part dropped: {reason}"),
                        });
                    }
                }
            }
        }
    }

    // Attach parts: explicit link first, then containment in the R*-tree.
    let tree = RTree::bulk_load(
        buildings
            .iter()
            .enumerate()
            .filter_map(|(i, b)| {
                let r = b.footprint.bounding_rect()?;
                Some(GeomWithData::new(
                    Rectangle::from_corners([r.min().x, r.min().y], [r.max().x, r.max().y]),
                    i,
                ))
            })
            .collect(),
    );
    let areas_m2: Vec<f64> = buildings
        .iter()
        .map(|b| b.footprint.unsigned_area())
        .collect();
    // Each part's building, found on every thread: by its explicit link when that names a
    // loaded building (else `true`: the link is reported), else by containment.
    let owners: Vec<(Option<usize>, bool)> = parts
        .par_iter()
        .map(|part| {
            let linked = part.part_of.as_ref().map(|name| link.get(name).copied());
            let owner = linked.flatten().or_else(|| {
                let p = part.footprint.interior_point()?;
                tree.locate_in_envelope_intersecting(AABB::from_point([p.x(), p.y()]))
                    .map(|g| g.data)
                    .filter(|&i| buildings[i].footprint.intersects(&p))
                    .min_by(|&a, &b| areas_m2[a].total_cmp(&areas_m2[b]))
            });
            (owner, linked == Some(None))
        })
        .collect();
    drop((tree, areas_m2, link));
    let mut parts_of = vec![0usize; buildings.len()];
    for &(owner, _) in &owners {
        if let Some(i) = owner {
            parts_of[i] += 1;
        }
    }
    for (building, &count) in buildings.iter_mut().zip(&parts_of) {
        building.parts.reserve_exact(count);
    }
    let mut orphans: Vec<String> = Vec::new();
    for (part, (owner, unlinked)) in parts.into_iter().zip(owners) {
        if unlinked {
            let name = part.part_of.as_deref().unwrap_or_default();
            report.warnings.push(LoadWarning {
                file: path.to_path_buf(),
                source_id: part.source_id.clone(),
                message: format!(
                    "part_of names {name:?}, which is not a loaded building; attached by \
                     containment instead"
                ),
            });
        }
        match owner {
            Some(i) => attach_part(&mut buildings[i], own_heights[i], part),
            None => orphans.push(part.source_id),
        }
    }
    for (building, own) in buildings.iter_mut().zip(&own_heights) {
        finish_building(building, *own, &mut report);
    }
    for orphan in orphans {
        report.warnings.push(LoadWarning {
            file: path.to_path_buf(),
            source_id: orphan,
            message: "building:part inside no building outline: dropped (it is not counted as \
                      a building, so it cannot be loaded as one)"
                .into(),
        });
    }
    report.buildings_loaded = buildings.len();

    let mut city_streets = Vec::new();
    if options.load_streets {
        for s in streets {
            report.streets_found += 1;
            let points = match s.points.and_then(|p| street_line(p, &project)) {
                Ok(points) => points,
                Err(reason) => {
                    report.streets_rejected.push(Rejection {
                        file: path.to_path_buf(),
                        source_id: s.source_id,
                        reason,
                    });
                    continue;
                }
            };
            city_streets.push(Street {
                source_id: s.source_id,
                class: s.class,
                name: s.name,
                line: LineString::new(points),
                tagged_width_m: s.tagged_width_m,
            });
        }
    }
    report.streets_loaded = city_streets.len();
    report.ground_areas_loaded = ground_areas.len();

    if buildings.is_empty() {
        return Err(LoadError::nothing_loaded(path, &report));
    }
    let mut city = City {
        frame,
        buildings,
        streets: city_streets,
        ground_areas,
        report,
    };
    city.renumber();
    Ok(city)
}

/// The frame, and for each area the reason it lies outside any frame of this city (`None` for
/// the rest); `None` when no area has a usable coordinate.
///
/// A single far outlier must not move the origin away from the city (issue 14: one building
/// at 1e15 m rejected them all), so the centre is found robustly first: the per-coordinate
/// median of the areas' box centres (buildings, or parts when no building has a usable
/// coordinate). Areas with a coordinate beyond [`MAX_LOCAL_COORDINATE_M`] of that centre are
/// outliers; the frame is then at the centre of the bounding box of the other areas, which
/// all lie within that distance of the new origin too (half a box at most that wide).
fn make_frame(crs: &SourceCrs, areas: &RawAreas) -> Option<(Frame, Vec<Option<RejectReason>>)> {
    let none = || vec![None; areas.len()];
    if *crs == SourceCrs::Local {
        return Some((Frame::local(), none()));
    }
    let usable = |c: &Coord<f64>| {
        c.x.is_finite()
            && c.y.is_finite()
            && (*crs != SourceCrs::Wgs84 || (c.x.abs() <= 180.0 && c.y.abs() <= 90.0))
    };
    let coords = |a: &RawArea| {
        a.polygons
            .as_ref()
            .ok()
            .into_iter()
            .flatten()
            .flatten()
            .flatten()
            .copied()
            .filter(usable)
            .collect::<Vec<_>>()
    };
    let boxes: Vec<Option<geo::Rect<f64>>> = areas
        .iter()
        .map(|a| {
            let c = coords(a);
            let first = *c.first()?;
            let (lo, hi) = c.iter().fold((first, first), |(lo, hi), p| {
                (
                    Coord {
                        x: lo.x.min(p.x),
                        y: lo.y.min(p.y),
                    },
                    Coord {
                        x: hi.x.max(p.x),
                        y: hi.y.max(p.y),
                    },
                )
            });
            Some(geo::Rect::new(lo, hi))
        })
        .collect();
    let kind = if areas
        .iter()
        .zip(&boxes)
        .any(|(a, b)| a.kind == AreaKind::Building && b.is_some())
    {
        AreaKind::Building
    } else {
        AreaKind::Part
    };
    let of_kind = || {
        areas
            .iter()
            .zip(&boxes)
            .filter(|(a, _)| a.kind == kind)
            .filter_map(|(_, b)| *b)
    };
    let median = |mut v: Vec<f64>| {
        let mid = v.len() / 2;
        *v.select_nth_unstable_by(mid, f64::total_cmp).1
    };
    let centres: Vec<Coord<f64>> = of_kind().map(|b| b.center()).collect();
    if centres.is_empty() {
        return None;
    }
    let centre = Coord {
        x: median(centres.iter().map(|c| c.x).collect()),
        y: median(centres.iter().map(|c| c.y).collect()),
    };
    let frame_at = |c: Coord<f64>| match crs {
        SourceCrs::Wgs84 => Frame::wgs84(c.x, c.y),
        SourceCrs::Projected(name) => Frame::projected(name.clone(), [c.x, c.y, 0.0]),
        SourceCrs::Local => Frame::local(),
    };
    let provisional = frame_at(centre);
    let outliers: Vec<Option<RejectReason>> = areas
        .iter()
        .map(|a| {
            let far = coords(a).into_iter().find_map(|c| {
                let p = provisional.to_local(DVec3::new(c.x, c.y, 0.0));
                let d = p.x.abs().max(p.y.abs());
                (d > MAX_LOCAL_COORDINATE_M || d.is_nan()).then_some((c, d))
            })?;
            let ((c, d), limit_km) = (far, MAX_LOCAL_COORDINATE_M / 1000.0);
            Some(RejectReason::CoordinateOutOfRange(format!(
                "({}, {}) is {:.0} km from the middle of the city's buildings, beyond \
                 {limit_km:.0} km",
                c.x,
                c.y,
                d / 1000.0
            )))
        })
        .collect();
    let kept = areas
        .iter()
        .zip(&boxes)
        .zip(&outliers)
        .filter(|((a, _), far)| a.kind == kind && far.is_none())
        .filter_map(|((_, b), _)| *b)
        .reduce(|a, b| {
            geo::Rect::new(
                Coord {
                    x: a.min().x.min(b.min().x),
                    y: a.min().y.min(b.min().y),
                },
                Coord {
                    x: a.max().x.max(b.max().x),
                    y: a.max().y.max(b.max().y),
                },
            )
        });
    let frame = kept.map_or(provisional, |b| frame_at(b.center()));
    Some((frame, outliers))
}

/// Gives heights to one area whose polygons were projected and cleaned (`cleaned`). On failure
/// returns its id and the reason.
fn validate_area(
    area: RawArea,
    cleaned: Result<CleanFootprint, RejectReason>,
    options: &LoadOptions,
) -> Result<(Area2, Vec<String>), (String, RejectReason)> {
    let RawArea {
        source_id,
        tags,
        heights,
        part_of,
        ..
    } = area;
    let fail = |reason| (source_id.clone(), reason);
    let clean = cleaned.map_err(fail)?;
    let resolved = heights.resolve(options);
    check_heights(resolved.base_m, resolved.top_m).map_err(fail)?;
    Ok((
        Area2 {
            source_id,
            footprint: clean.footprint,
            heights: resolved,
            has_own_heights: heights.has_top(),
            tags,
            part_of,
        },
        clean.repairs,
    ))
}

/// Projects an area's polygons into the local frame and cleans them
/// ([`crate::validate::clean_footprint`]).
fn clean_polygons(
    polygons: RawPolygons,
    project: &impl Fn(Coord<f64>) -> Result<Coord<f64>, RejectReason>,
) -> Result<CleanFootprint, RejectReason> {
    let mut local: RawPolygons = Vec::with_capacity(polygons.len());
    for rings in polygons {
        let mut out_rings = Vec::with_capacity(rings.len());
        for ring in rings {
            out_rings.push(
                ring.into_iter()
                    .map(project)
                    .collect::<Result<Vec<_>, _>>()?,
            );
        }
        local.push(out_rings);
    }
    // A panic inside the overlay that repairs crossing rings rejects this area only
    // (`overlay_guard`).
    clean_footprint(&local)
}

impl Area2 {
    /// The model's building, its heights its own until its parts are attached
    /// ([`attach_part`], [`finish_building`]).
    fn into_building(self) -> Building {
        Building {
            id: BuildingId(0),
            source_id: self.source_id,
            footprint: self.footprint,
            parts: Vec::new(),
            base_m: self.heights.base_m,
            top_m: self.heights.top_m,
            height_source: self.heights.source,
            mesh: None,
            tags: self.tags,
        }
    }

    /// What a part keeps while its building is looked for (parts carry no tags).
    fn into_part(self) -> ValidPart {
        ValidPart {
            source_id: self.source_id,
            footprint: self.footprint,
            heights: self.heights,
            has_own_heights: self.has_own_heights,
            part_of: self.part_of,
        }
    }
}

/// Attaches a part to its building (whose own heights are `own`): a part with no heights of
/// its own takes the building's; the building's height source becomes the best of its own
/// and its parts'.
fn attach_part(building: &mut Building, own: ResolvedHeights, part: ValidPart) {
    let h = if part.has_own_heights {
        part.heights
    } else {
        own
    };
    building.height_source = better_source(building.height_source, h.source);
    building.parts.push(BuildingPart {
        source_id: part.source_id,
        footprint: part.footprint,
        base_m: h.base_m,
        top_m: h.top_m,
    });
}

/// Completes a building once its parts are attached: one without parts is its own single
/// part; its heights span its parts'. Counts its own heights in the report.
fn finish_building(building: &mut Building, own: ResolvedHeights, report: &mut LoadReport) {
    if building.parts.is_empty() {
        building.parts.push(BuildingPart {
            source_id: building.source_id.clone(),
            footprint: building.footprint.clone(),
            base_m: own.base_m,
            top_m: own.top_m,
        });
    }
    building.base_m = building
        .parts
        .iter()
        .map(|p| p.base_m)
        .fold(f32::INFINITY, f32::min);
    building.top_m = building
        .parts
        .iter()
        .map(|p| p.top_m)
        .fold(f32::NEG_INFINITY, f32::max);
    // The report counts the building's own tags, as OSM statistics do (a building without a
    // height whose parts have one is not "with height"); `height_source` is the best source of
    // the heights actually used.
    match own.source {
        HeightSource::Tagged => report.buildings_with_height += 1,
        HeightSource::Estimated => report.buildings_estimated_height += 1,
        HeightSource::Levels | HeightSource::Geometry => {}
    }
}

/// The more trustworthy of two height sources (tagged metres, levels, estimate).
fn better_source(a: HeightSource, b: HeightSource) -> HeightSource {
    let rank = |s| match s {
        HeightSource::Geometry => 0,
        HeightSource::Tagged => 1,
        HeightSource::Levels => 2,
        HeightSource::Estimated => 3,
    };
    if rank(b) < rank(a) { b } else { a }
}

/// Shortest street line kept (metres): anything shorter is a stray point.
const MIN_STREET_LENGTH_M: f64 = 0.01;

/// A street's points in the local frame, consecutive repeats dropped; every coordinate must
/// be finite and within the local range, and the line must have two distinct points and a
/// length.
fn street_line(
    points: Vec<Coord<f64>>,
    project: &impl Fn(Coord<f64>) -> Result<Coord<f64>, RejectReason>,
) -> Result<Vec<Coord<f64>>, RejectReason> {
    let mut local = Vec::with_capacity(points.len());
    for c in points {
        let p = project(c)?;
        if !(p.x.abs() <= MAX_LOCAL_COORDINATE_M && p.y.abs() <= MAX_LOCAL_COORDINATE_M) {
            return Err(RejectReason::CoordinateOutOfRange(format!(
                "({}, {}) is beyond {} km of the origin",
                c.x,
                c.y,
                MAX_LOCAL_COORDINATE_M / 1000.0
            )));
        }
        local.push(p);
    }
    local.dedup();
    if local.len() < 2 {
        return Err(RejectReason::InvalidGeometry(format!(
            "a street needs 2 distinct points, it has {}",
            local.len()
        )));
    }
    let length_m: f64 = local
        .windows(2)
        .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
        .sum();
    if length_m.is_nan() || length_m < MIN_STREET_LENGTH_M {
        return Err(RejectReason::InvalidGeometry(format!(
            "street of zero length ({length_m} m)"
        )));
    }
    Ok(local)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load::heights::HeightKeys;

    fn area(id: &str, kind: AreaKind, x: f64, y: f64, s: f64, tags: &[(&str, &str)]) -> RawArea {
        let ring = vec![
            Coord { x, y },
            Coord { x: x + s, y },
            Coord { x: x + s, y: y + s },
            Coord { x, y: y + s },
        ];
        let tags: Tags = tags.iter().copied().collect();
        let heights =
            TaggedHeights::read(|k| tags.get(k), &HeightKeys::osm(), &LoadOptions::default());
        RawArea {
            source_id: id.into(),
            kind,
            polygons: Ok(vec![vec![ring]]),
            tags,
            heights,
            link_ids: Vec::new(),
            part_of: None,
        }
    }

    #[test]
    fn part_goes_to_the_smallest_containing_outline() {
        let inner_part = area("p", AreaKind::Part, 12.0, 12.0, 2.0, &[("height", "40")]);
        let mut linked = area("q", AreaKind::Part, 1.0, 1.0, 2.0, &[]);
        linked.part_of = Some("nowhere".into());
        let raw = RawCity {
            crs: SourceCrs::Local,
            areas: [
                area(
                    "big",
                    AreaKind::Building,
                    0.0,
                    0.0,
                    100.0,
                    &[("height", "10")],
                ),
                area(
                    "small",
                    AreaKind::Building,
                    10.0,
                    10.0,
                    10.0,
                    &[("height", "30")],
                ),
                inner_part,
                linked,
            ]
            .into_iter()
            .collect(),
            streets: Vec::new(),
            warnings: Vec::new(),
        };
        let city = assemble(Path::new("t.geojson"), raw, &LoadOptions::default()).unwrap();
        city.check_invariants().unwrap();
        let small = city
            .buildings
            .iter()
            .find(|b| b.source_id == "small")
            .unwrap();
        assert_eq!(small.parts.len(), 1);
        assert_eq!(small.parts[0].source_id, "p");
        assert_eq!(small.top_m, 40.0);
        // The unresolved part_of falls back to containment (in "big"), with a warning, and the
        // part without heights inherits its building's.
        let big = city
            .buildings
            .iter()
            .find(|b| b.source_id == "big")
            .unwrap();
        assert_eq!(big.parts.len(), 1);
        assert_eq!(
            (big.parts[0].source_id.as_str(), big.parts[0].top_m),
            ("q", 10.0)
        );
        assert!(city.report.warnings.iter().any(|w| w.source_id == "q"));
        assert_eq!(city.report.buildings_with_height, 2);
    }

    /// Parts read chunks after their buildings (the assembly takes the raw areas a chunk at a
    /// time) find them by link and by containment; warnings come in the order of the areas
    /// they are about, links before orphans.
    #[test]
    fn parts_find_buildings_read_chunks_before_them() {
        let n = 1500;
        let mut areas: Vec<RawArea> = (0..n)
            .map(|i| {
                let (x, y) = ((i % 50) as f64 * 20.0, (i / 50) as f64 * 20.0);
                area(
                    &format!("b{i}"),
                    AreaKind::Building,
                    x,
                    y,
                    10.0,
                    &[("height", "10")],
                )
            })
            .collect();
        for i in (0..n).rev().step_by(3) {
            let (x, y) = ((i % 50) as f64 * 20.0, (i / 50) as f64 * 20.0);
            let mut part = area(&format!("p{i}"), AreaKind::Part, x + 1.0, y + 1.0, 2.0, &[]);
            // Every other part linked; a third of those by a name no building has.
            part.part_of = match i % 6 {
                0 => Some(format!("b{i}")),
                3 => Some(format!("missing{i}")),
                _ => None,
            };
            areas.push(part);
        }
        areas.push(area("orphan", AreaKind::Part, -500.0, -500.0, 2.0, &[]));
        areas.push(area(
            "unlinked-orphan",
            AreaKind::Part,
            -900.0,
            0.0,
            2.0,
            &[],
        ));
        areas.last_mut().unwrap().part_of = Some("nobody".into());
        let raw = RawCity {
            crs: SourceCrs::Local,
            areas: areas.into_iter().collect(),
            streets: Vec::new(),
            warnings: Vec::new(),
        };
        let city = assemble(Path::new("t.geojson"), raw, &LoadOptions::default()).unwrap();
        city.check_invariants().unwrap();
        assert_eq!(city.buildings.len(), n);
        for (i, b) in city.buildings.iter().enumerate() {
            let expected = if i % 3 == (n - 1) % 3 {
                format!("p{i}")
            } else {
                format!("b{i}")
            };
            assert_eq!(b.parts.len(), 1, "{}", b.source_id);
            assert_eq!(b.parts[0].source_id, expected);
            assert_eq!(b.top_m, 10.0, "a part without heights takes its building's");
        }
        let about: Vec<&str> = city
            .report
            .warnings
            .iter()
            .map(|w| w.source_id.as_str())
            .collect();
        let mut expected: Vec<String> = (0..n)
            .rev()
            .step_by(3)
            .filter(|i| i % 6 == 3)
            .map(|i| format!("p{i}"))
            .collect();
        expected.extend([
            "unlinked-orphan".into(),
            "orphan".into(),
            "unlinked-orphan".into(),
        ]);
        assert_eq!(about, expected);
        assert_eq!(city.report.parts_found, n / 3 + 2);
    }
}
