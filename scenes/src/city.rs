//! The one city model every loader produces and every later stage consumes.
//!
//! Coordinates are in a local metric frame (east, north, up; metres) whose geographic origin is
//! kept in [`Frame`]. Footprints are `geo` polygons in f64 (exact predicates want f64); meshes are
//! f32 (`glam::Vec3`), which is ample within a few tens of kilometres of the origin.

use geo::{Area, BoundingRect, MultiPolygon};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::frame::Frame;
use crate::report::LoadReport;
use crate::tags::Tags;

/// Index of a building in [`City::buildings`]; stable for a given input and loader options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct BuildingId(pub u32);

impl BuildingId {
    /// The index into [`City::buildings`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// A triangle mesh in the local frame (z up), counter-clockwise seen from outside.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3>,
    /// Three indices per triangle into `positions`.
    pub indices: Vec<u32>,
}

impl TriangleMesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Iterates over the triangles as corner triples.
    pub fn triangles(&self) -> impl Iterator<Item = [Vec3; 3]> + '_ {
        self.indices.chunks_exact(3).map(|t| {
            [
                self.positions[t[0] as usize],
                self.positions[t[1] as usize],
                self.positions[t[2] as usize],
            ]
        })
    }

    /// Appends `other`, re-basing its indices.
    pub fn append(&mut self, other: &TriangleMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.indices.extend(other.indices.iter().map(|i| i + base));
    }

    /// Axis-aligned bounds `(min, max)`, or `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }
}

/// One vertical extrusion of a building: a footprint between two heights.
///
/// 2.5D inputs (GeoJSON, OSM) describe a building by one part (its outline) or, following the
/// OSM Simple 3D Buildings rules, by the `building:part` areas that replace the outline.
/// Mesh inputs (CityJSON, glTF) have one part per source part, with the footprint derived
/// from its mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BuildingPart {
    /// Identifier of the part in its source (for example `way/123`), or of the building itself
    /// when the building has no separate parts.
    pub source_id: String,
    /// Footprint in the local frame: one or more polygons, holes kept. Valid (see
    /// [`crate::validate`]): finite, simple rings, positive area.
    pub footprint: MultiPolygon<f64>,
    /// Height of the bottom of the part above the frame's ground (metres).
    pub base_m: f32,
    /// Height of the top of the part (metres).
    pub top_m: f32,
}

/// Where a building's heights came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum HeightSource {
    /// A height tag or property in metres.
    Tagged,
    /// Derived from a number of levels times a level height.
    Levels,
    /// Measured from 3D geometry.
    Geometry,
    /// No height was given: a documented default was used ([`crate::load::LoadOptions`]).
    Estimated,
}

/// One building of the city.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Building {
    pub id: BuildingId,
    /// Identifier in the source (OSM `way/123`, CityJSON object id, glTF feature id, ...).
    pub source_id: String,
    /// Outline of the whole building in the local frame (the union of its parts' outlines).
    pub footprint: MultiPolygon<f64>,
    /// The vertical parts; never empty (but for a package read only to draw it,
    /// [`crate::package::Decode::Runtime`]).
    ///
    /// Not serialized with the building: a package keeps parts and tags in a section of their
    /// own, which drawing the scene never decodes ([`crate::package::format`]).
    #[serde(skip)]
    pub parts: Vec<BuildingPart>,
    /// Lowest base over all parts (metres).
    pub base_m: f32,
    /// Highest top over all parts (metres).
    pub top_m: f32,
    pub height_source: HeightSource,
    /// The source's own geometry when it has true 3D geometry (CityJSON, glTF). Boxed: most
    /// buildings have none, and a million of them would each carry an empty mesh's 48 bytes.
    pub mesh: Option<Box<TriangleMesh>>,
    /// Source attributes / tags, as strings (in the package's section with the parts).
    #[serde(skip)]
    pub tags: Tags,
}

/// Tag keys whose value is a building's number of storeys above ground (OSM, CityJSON).
pub const LEVEL_TAGS: [&str; 3] = ["building:levels", "storeysAboveGround", "levels"];

/// The storeys above ground as `tags` give them ([`LEVEL_TAGS`], first found), if at all.
pub fn levels_tag(tags: &Tags) -> Option<&str> {
    LEVEL_TAGS.iter().find_map(|k| tags.get(k))
}

impl Building {
    /// The building's storeys above ground as its source tags them ([`LEVEL_TAGS`]), if at all.
    pub fn levels_tag(&self) -> Option<&str> {
        levels_tag(&self.tags)
    }

    /// Footprint area in square metres.
    pub fn footprint_area_m2(&self) -> f64 {
        self.footprint.unsigned_area()
    }

    /// Height of the top above the base (metres).
    pub fn height_m(&self) -> f32 {
        self.top_m - self.base_m
    }

    /// Axis-aligned bounds in the local frame.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (mut lo, mut hi) = match self.footprint.bounding_rect() {
            Some(r) => (
                Vec3::new(r.min().x as f32, r.min().y as f32, self.base_m),
                Vec3::new(r.max().x as f32, r.max().y as f32, self.top_m),
            ),
            None => (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        };
        if let Some((mlo, mhi)) = self.mesh.as_deref().and_then(TriangleMesh::bounds) {
            lo = lo.min(mlo);
            hi = hi.max(mhi);
        }
        (lo, hi)
    }
}

/// Classification of a street, from OSM `highway=*` or the generator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum StreetClass {
    Major,
    Minor,
    Residential,
    Service,
    Pedestrian,
    Other,
}

impl StreetClass {
    /// Maps an OSM `highway=*` value to a class.
    pub fn from_osm_highway(value: &str) -> StreetClass {
        match value {
            "motorway" | "trunk" | "primary" | "secondary" | "motorway_link" | "trunk_link"
            | "primary_link" | "secondary_link" => StreetClass::Major,
            "tertiary" | "tertiary_link" | "unclassified" => StreetClass::Minor,
            "residential" | "living_street" => StreetClass::Residential,
            "service" => StreetClass::Service,
            "pedestrian" | "footway" | "path" | "steps" | "cycleway" => StreetClass::Pedestrian,
            _ => StreetClass::Other,
        }
    }

    /// Whether streets of this class separate urban blocks (Lynch's paths). Footways and
    /// service roads run inside blocks and do not.
    pub fn bounds_blocks(self) -> bool {
        matches!(
            self,
            StreetClass::Major | StreetClass::Minor | StreetClass::Residential
        )
    }

    /// The carriageway width in metres when the source gives none (OSM `width` / `lanes`):
    /// a two-lane road of its class, after typical urban cross-sections (3.0–3.5 m lanes,
    /// wider for arterials; footways 3 m).
    pub fn default_width_m(self) -> f32 {
        match self {
            StreetClass::Major => 14.0,
            StreetClass::Minor => 10.0,
            StreetClass::Residential => 7.0,
            StreetClass::Service => 4.5,
            StreetClass::Pedestrian => 3.0,
            StreetClass::Other => 4.0,
        }
    }

    /// A short stable name, used in files.
    pub fn name(self) -> &'static str {
        match self {
            StreetClass::Major => "major",
            StreetClass::Minor => "minor",
            StreetClass::Residential => "residential",
            StreetClass::Service => "service",
            StreetClass::Pedestrian => "pedestrian",
            StreetClass::Other => "other",
        }
    }

    /// Inverse of [`StreetClass::name`].
    pub fn from_name(name: &str) -> Option<StreetClass> {
        [
            StreetClass::Major,
            StreetClass::Minor,
            StreetClass::Residential,
            StreetClass::Service,
            StreetClass::Pedestrian,
            StreetClass::Other,
        ]
        .into_iter()
        .find(|c| c.name() == name)
    }
}

/// A street centre line in the local frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Street {
    pub source_id: String,
    pub class: StreetClass,
    pub name: Option<String>,
    pub line: geo::LineString<f64>,
    /// The width the source gives (OSM `width`, else `lanes` × a lane), in metres; `None`
    /// when it gives none ([`Street::width_m`] then uses the class's default).
    pub tagged_width_m: Option<f32>,
}

impl Street {
    /// The street's surface width in metres: the source's, else the class default.
    pub fn width_m(&self) -> f32 {
        self.tagged_width_m
            .unwrap_or_else(|| self.class.default_width_m())
    }
}

/// What a ground area is, for its colour and its draw order (later classes lie on top). The
/// sources' tags and classes map to it in one place each: [`GroundClass::from_osm_tags`] (OSM,
/// GeoJSON) and [`GroundClass::from_class_name`] (3dfier OBJ).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum GroundClass {
    /// Farmland, meadow, grass, cemeteries and other open land (OSM `landuse=grass|meadow|…`).
    Grass,
    /// Woods and forest (OSM `natural=wood`, `landuse=forest`; 3dfier `Forest`).
    Forest,
    /// Parks, gardens and pitches (OSM `leisure=park|garden|pitch|playground`).
    Park,
    /// Paved open space: squares, parking, plazas (OSM `amenity=parking`, `place=square`,
    /// `area:highway`; 3dfier `Road` and `Bridge` surfaces).
    Paved,
    /// Water bodies (OSM `natural=water`, `waterway=riverbank`; 3dfier `Water`).
    Water,
    /// Any other classified land (OSM `landuse=*` not above; 3dfier `Terrain`).
    Other,
}

impl GroundClass {
    /// Every class, in draw order.
    pub const ALL: [GroundClass; 6] = [
        GroundClass::Other,
        GroundClass::Grass,
        GroundClass::Forest,
        GroundClass::Park,
        GroundClass::Paved,
        GroundClass::Water,
    ];

    /// A short stable name, used in files and reports.
    pub fn name(self) -> &'static str {
        match self {
            GroundClass::Grass => "grass",
            GroundClass::Forest => "forest",
            GroundClass::Park => "park",
            GroundClass::Paved => "paved",
            GroundClass::Water => "water",
            GroundClass::Other => "other",
        }
    }

    /// Inverse of [`GroundClass::name`].
    pub fn from_name(name: &str) -> Option<GroundClass> {
        GroundClass::ALL.into_iter().find(|c| c.name() == name)
    }

    /// The class of an area from its OSM tags (OSM ways and relations, and GeoJSON properties,
    /// which carry the same tags), or `None` when the tags make no ground area. `tag` answers
    /// a key's value. The caller decides first that the element is not a building or a
    /// building part: a building is never also a ground area.
    ///
    /// The first matching rule wins, so that a pond tagged inside a park is water and a
    /// pitch on a recreation ground a park:
    /// 1. Water: `natural=water`, `waterway=riverbank`, `water=*`, `landuse=reservoir|basin`.
    /// 2. Paved: `area:highway=*`, `highway=*` with `area=yes` (a pedestrian plaza drawn as
    ///    an area), `place=square`, `amenity=parking` (not `parking=underground`).
    /// 3. Park: `leisure=park|garden|pitch|playground|common|nature_reserve|dog_park`.
    /// 4. Forest: `natural=wood`, `landuse=forest`.
    /// 5. Grass: `natural=grassland|scrub|heath|wetland`, `landuse=grass|meadow|village_green|
    ///    cemetery|farmland|recreation_ground|allotments|orchard|vineyard`.
    /// 6. Other: any other `landuse=*`.
    ///
    /// A value `no` counts as absent.
    pub fn from_osm_tags<'a>(tag: impl Fn(&str) -> Option<&'a str>) -> Option<GroundClass> {
        let tag = |k: &str| tag(k).filter(|v| !v.is_empty() && *v != "no");
        let is = |k: &str, values: &[&str]| tag(k).is_some_and(|v| values.contains(&v));
        let natural = |values: &[&str]| is("natural", values);
        let landuse = |values: &[&str]| is("landuse", values);
        if natural(&["water"])
            || is("waterway", &["riverbank"])
            || tag("water").is_some()
            || landuse(&["reservoir", "basin"])
        {
            return Some(GroundClass::Water);
        }
        if tag("area:highway").is_some()
            || (tag("highway").is_some() && is("area", &["yes"]))
            || is("place", &["square"])
            || (is("amenity", &["parking"]) && !is("parking", &["underground"]))
        {
            return Some(GroundClass::Paved);
        }
        let parks = [
            "park",
            "garden",
            "pitch",
            "playground",
            "common",
            "nature_reserve",
            "dog_park",
        ];
        if is("leisure", &parks) {
            return Some(GroundClass::Park);
        }
        if natural(&["wood"]) || landuse(&["forest"]) {
            return Some(GroundClass::Forest);
        }
        let grass = [
            "grass",
            "meadow",
            "village_green",
            "cemetery",
            "farmland",
            "recreation_ground",
            "allotments",
            "orchard",
            "vineyard",
        ];
        if natural(&["grassland", "scrub", "heath", "wetland"]) || landuse(&grass) {
            return Some(GroundClass::Grass);
        }
        tag("landuse").map(|_| GroundClass::Other)
    }

    /// The class of a mesh object from a class name of its source: a 3dfier class (its OBJ
    /// material or object name: `Terrain`, `Forest`, `Water`, `Road`, `Bridge`,
    /// `Separation`), matched as an ASCII case-insensitive substring. `Road` and `Bridge`
    /// (also `Overpass`) are paved (a bridge's deck is drawn in plan, as a road); `Terrain`,
    /// `Separation` (walls, fences) and anything unknown are `None`, which callers read as
    /// [`GroundClass::Other`] after trying the object's other names.
    pub fn from_class_name(name: &str) -> Option<GroundClass> {
        let name = name.to_ascii_lowercase();
        let has = |words: &[&str]| words.iter().any(|w| name.contains(w));
        if has(&["water"]) {
            Some(GroundClass::Water)
        } else if has(&["road", "bridge", "overpass"]) {
            Some(GroundClass::Paved)
        } else if has(&["forest"]) {
            Some(GroundClass::Forest)
        } else {
            None
        }
    }
}

/// An area of the ground that is not a building or a street (water, a park, a square), in the
/// local frame. Drawn on the ground plane; it never occludes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroundArea {
    pub source_id: String,
    pub class: GroundClass,
    pub polygon: MultiPolygon<f64>,
}

/// A loaded city: buildings and streets in one local frame, with the load report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct City {
    pub frame: Frame,
    pub buildings: Vec<Building>,
    pub streets: Vec<Street>,
    /// Water, parks, squares and other ground areas.
    pub ground_areas: Vec<GroundArea>,
    pub report: LoadReport,
}

impl City {
    /// Moves every building's heap data (ids, footprints, parts, tags) into fresh allocations,
    /// one building after another, each original freed once copied. The loaders make buildings
    /// on every thread amid their parsing's short-lived allocations, whose pages the survivors
    /// would keep resident for the whole run: a generated city of a million buildings held
    /// 1.6 GB after the blocks step as loaded, 0.93 GB compacted (BENCHMARKS.md).
    pub fn compact_buildings(&mut self) {
        let buildings = std::mem::take(&mut self.buildings);
        self.buildings = buildings
            .into_iter()
            .map(|loaded| {
                let fresh = loaded.clone();
                drop(loaded);
                fresh
            })
            .collect();
    }

    /// Bounds of all buildings `(min, max)`, or `None` for an empty city.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.buildings
            .iter()
            .map(Building::bounds)
            .reduce(|(alo, ahi), (blo, bhi)| (alo.min(blo), ahi.max(bhi)))
    }

    /// Renumbers building ids to their positions; loaders call this after filtering.
    pub fn renumber(&mut self) {
        for (i, b) in self.buildings.iter_mut().enumerate() {
            b.id = BuildingId(i as u32);
        }
    }

    /// Checks the model's invariants: ids are positions, every building has parts, heights are
    /// ordered and finite, footprints and ground areas are valid. Returns the first violation
    /// found.
    pub fn check_invariants(&self) -> Result<(), String> {
        for (i, b) in self.buildings.iter().enumerate() {
            if b.id.index() != i {
                return Err(format!("building {} has id {:?}", i, b.id));
            }
            if b.parts.is_empty() {
                return Err(format!("building {} has no parts", b.source_id));
            }
            if !(b.base_m.is_finite() && b.top_m.is_finite() && b.top_m > b.base_m) {
                return Err(format!(
                    "building {} has heights {}..{}",
                    b.source_id, b.base_m, b.top_m
                ));
            }
            crate::validate::check_multipolygon(&b.footprint)
                .map_err(|r| format!("building {}: footprint {r}", b.source_id))?;
            for p in &b.parts {
                crate::validate::check_multipolygon(&p.footprint)
                    .map_err(|r| format!("part {}: footprint {r}", p.source_id))?;
                if p.top_m.partial_cmp(&p.base_m) != Some(std::cmp::Ordering::Greater)
                    || p.base_m < b.base_m
                    || p.top_m > b.top_m
                {
                    return Err(format!(
                        "part {} heights {}..{} outside building {}..{}",
                        p.source_id, p.base_m, p.top_m, b.base_m, b.top_m
                    ));
                }
            }
        }
        for g in &self.ground_areas {
            crate::validate::check_multipolygon(&g.polygon)
                .map_err(|r| format!("ground area {}: polygon {r}", g.source_id))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::GroundClass;

    fn class(tags: &[(&str, &str)]) -> Option<GroundClass> {
        GroundClass::from_osm_tags(|k| tags.iter().find(|(key, _)| *key == k).map(|(_, v)| *v))
    }

    #[test]
    fn osm_tags_map_to_ground_classes_first_rule_winning() {
        use GroundClass::*;
        assert_eq!(class(&[("natural", "water")]), Some(Water));
        assert_eq!(
            class(&[("water", "pond"), ("leisure", "park")]),
            Some(Water)
        );
        assert_eq!(class(&[("waterway", "riverbank")]), Some(Water));
        assert_eq!(
            class(&[("highway", "pedestrian"), ("area", "yes")]),
            Some(Paved)
        );
        assert_eq!(class(&[("highway", "pedestrian")]), None);
        assert_eq!(class(&[("area:highway", "footway")]), Some(Paved));
        assert_eq!(class(&[("place", "square")]), Some(Paved));
        assert_eq!(class(&[("amenity", "parking")]), Some(Paved));
        let underground = [("amenity", "parking"), ("parking", "underground")];
        assert_eq!(class(&underground), None);
        let pitch = [("leisure", "pitch"), ("landuse", "recreation_ground")];
        assert_eq!(class(&pitch), Some(Park));
        assert_eq!(class(&[("natural", "wood")]), Some(Forest));
        assert_eq!(class(&[("landuse", "forest")]), Some(Forest));
        assert_eq!(class(&[("landuse", "cemetery")]), Some(Grass));
        assert_eq!(class(&[("natural", "scrub")]), Some(Grass));
        assert_eq!(class(&[("landuse", "retail")]), Some(Other));
        assert_eq!(class(&[("landuse", "no")]), None);
        assert_eq!(class(&[("leisure", "sports_centre")]), None);
        assert_eq!(class(&[("name", "Hudson")]), None);
    }

    /// Compacting keeps every building as it was and leaves no spare capacity behind.
    #[test]
    fn compacted_buildings_are_the_same_without_slack() {
        use crate::generate::{GenerateParams, generate_city};
        let mut city = generate_city(&GenerateParams {
            buildings: 300,
            seed: 2,
            ..GenerateParams::default()
        })
        .expect("generate");
        for b in &mut city.buildings {
            b.parts.reserve(7);
            b.footprint.0[0].exterior_mut(|ring| ring.0.reserve(100));
        }
        let before = city.buildings.clone();
        city.compact_buildings();
        assert_eq!(city.buildings, before);
        for b in &city.buildings {
            assert_eq!(b.parts.capacity(), b.parts.len());
            assert_eq!(
                b.footprint.0[0].exterior().0.capacity(),
                b.footprint.0[0].exterior().0.len()
            );
        }
    }

    #[test]
    fn class_names_map_3dfier_classes() {
        use GroundClass::*;
        assert_eq!(GroundClass::from_class_name("Water"), Some(Water));
        assert_eq!(GroundClass::from_class_name("WaterBody"), Some(Water));
        assert_eq!(GroundClass::from_class_name("Road"), Some(Paved));
        assert_eq!(GroundClass::from_class_name("bridge_3"), Some(Paved));
        assert_eq!(GroundClass::from_class_name("FOREST"), Some(Forest));
        assert_eq!(GroundClass::from_class_name("Terrain"), None);
        assert_eq!(GroundClass::from_class_name("Separation"), None);
    }
}
