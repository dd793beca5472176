//! What the panel says about a picked building or cluster mesh ([`citywalk_runtime::pick`]):
//! its id, source id, height, levels and tags, or the tree node and the buildings it stands
//! for.

use citywalk_scenes::package::BuildingDetails;
use citywalk_scenes::{City, Tags};

/// The buildings' source ids, kept when the viewer frees the buildings of a package (one
/// string and its offsets: ~14 MB at a million buildings, against ~40 MB as strings).
#[derive(Debug, Clone, Default)]
pub struct SourceIds {
    text: String,
    ends: Vec<u32>,
}

impl SourceIds {
    pub fn of(city: &City) -> SourceIds {
        let mut ids = SourceIds::default();
        for b in &city.buildings {
            ids.text.push_str(&b.source_id);
            ids.ends.push(ids.text.len() as u32);
        }
        ids
    }

    /// The source id of building `id`.
    pub fn get(&self, id: u32) -> Option<&str> {
        let end = *self.ends.get(id as usize)? as usize;
        let start = match id {
            0 => 0,
            _ => self.ends[id as usize - 1] as usize,
        };
        self.text.get(start..end)
    }

    pub fn len(&self) -> usize {
        self.ends.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }
}

/// A pick, described.
#[derive(Debug, Clone, PartialEq)]
pub struct Picked {
    /// The draw id (tinted in the frames that follow).
    pub draw: u32,
    /// (name, value) rows for the panel.
    pub rows: Vec<(String, String)>,
    /// The building whose levels and tags are still to be read from its package
    /// ([`Picked::fill_details`] puts them in place of the row saying so).
    pub details_pending: Option<u32>,
}

/// The row that stands for a package building's levels and tags until they are read.
const READING: &str = "reading from the package…";

impl Picked {
    /// Puts the levels and tags of building `id`, read from its package, in place of the row
    /// that waited for them (a read that failed says why there); a pick of something else by
    /// now is left as it is.
    pub fn fill_details(&mut self, id: u32, read: Result<BuildingDetails, String>) {
        if self.details_pending != Some(id) {
            return;
        }
        self.details_pending = None;
        let Some(at) = self.rows.iter().position(|(_, v)| v == READING) else {
            return;
        };
        let rows = match read {
            Ok(details) => tag_rows(details.levels_tag(), &details.tags),
            Err(e) => vec![("tags".to_string(), format!("not read: {e}"))],
        };
        self.rows.splice(at..=at, rows);
    }
}

/// The levels row and the tags rows (at most [`LISTED_TAGS`]).
fn tag_rows(levels: Option<&str>, tags: &Tags) -> Vec<(String, String)> {
    let mut rows = Vec::new();
    if let Some(levels) = levels {
        rows.push(("levels".to_string(), levels.to_string()));
    }
    for (k, v) in tags.iter().take(LISTED_TAGS) {
        rows.push((k.to_string(), v.to_string()));
    }
    if tags.len() > LISTED_TAGS {
        rows.push((
            "…".to_string(),
            format!("{} more tags", tags.len() - LISTED_TAGS),
        ));
    }
    if tags.is_empty() {
        rows.push(("tags".to_string(), "none".to_string()));
    }
    rows
}

/// What is known of the draw under the cursor.
#[derive(Debug, Clone, Copy)]
pub struct PickFacts<'a> {
    pub draw: u32,
    pub distance_m: f32,
    pub building_count: u32,
    /// The draw's bounds (metres).
    pub bounds: ([f32; 3], [f32; 3]),
    /// The buildings a cluster draw stands for (empty for a building).
    pub covered: &'a [u32],
    pub source_ids: &'a SourceIds,
    /// The city's buildings, with their tags, where the viewer still holds them (a raw input);
    /// a package opened to draw keeps only their source ids.
    pub city: &'a City,
    /// The building's levels and tags can be read from the package the scene was opened from
    /// (they are not in `city`): the panel says they are being read.
    pub package_details: bool,
}

/// Buildings of a cluster listed by source id in the panel.
const LISTED_BUILDINGS: usize = 8;

/// Tags shown in the panel.
const LISTED_TAGS: usize = 24;

/// The panel rows of a pick.
pub fn describe(f: &PickFacts<'_>) -> Picked {
    let mut rows: Vec<(String, String)> = Vec::new();
    let mut details_pending = None;
    let mut row = |k: &str, v: String| rows.push((k.to_string(), v));
    let (lo, hi) = f.bounds;
    if f.draw < f.building_count {
        let id = f.draw;
        row("building", id.to_string());
        row(
            "source id",
            f.source_ids.get(id).unwrap_or("(not kept)").to_string(),
        );
        let building = f.city.buildings.get(id as usize);
        let height = building.map_or(hi[2] - lo[2], |b| b.height_m());
        row("height", format!("{height:.1} m"));
        if let Some(b) = building {
            row("base", format!("{:.1} m", b.base_m));
            row(
                "height from",
                format!("{:?}", b.height_source).to_lowercase(),
            );
            for (k, v) in tag_rows(b.levels_tag(), &b.tags) {
                row(&k, v);
            }
        } else if f.package_details {
            row("tags", READING.into());
            details_pending = Some(id);
        } else {
            row(
                "tags",
                "not loaded (a package is opened to draw; `inspect` lists them)".into(),
            );
        }
    } else {
        row("cluster node", (f.draw - f.building_count).to_string());
        row("stands for", format!("{} buildings", f.covered.len()));
        row("height", format!("{:.1} m", hi[2] - lo[2]));
        for &b in f.covered.iter().take(LISTED_BUILDINGS) {
            row(
                "  building",
                format!("{b} {}", f.source_ids.get(b).unwrap_or("")),
            );
        }
        if f.covered.len() > LISTED_BUILDINGS {
            row(
                "  …",
                format!("{} more", f.covered.len() - LISTED_BUILDINGS),
            );
        }
    }
    row("distance", format!("{:.1} m", f.distance_m));
    Picked {
        draw: f.draw,
        rows,
        details_pending,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use citywalk_scenes::{Building, BuildingId, Crs, Frame, HeightSource};

    fn city() -> City {
        let building = |id: u32, source: &str, levels: Option<&str>| Building {
            id: BuildingId(id),
            source_id: source.into(),
            footprint: geo::MultiPolygon::new(Vec::new()),
            parts: Vec::new(),
            base_m: 0.0,
            top_m: 12.0,
            height_source: HeightSource::Levels,
            mesh: None,
            tags: levels
                .map(|l| Tags::from([("building:levels", l)]))
                .unwrap_or_default(),
        };
        City {
            frame: Frame {
                crs: Crs::Local,
                origin: [0.0; 3],
            },
            buildings: vec![building(0, "way/1", Some("4")), building(1, "way/22", None)],
            streets: Vec::new(),
            ground_areas: Vec::new(),
            report: Default::default(),
        }
    }

    #[test]
    fn source_ids_are_kept_compactly() {
        let ids = SourceIds::of(&city());
        assert_eq!(ids.len(), 2);
        assert_eq!(ids.get(0), Some("way/1"));
        assert_eq!(ids.get(1), Some("way/22"));
        assert_eq!(ids.get(2), None);
    }

    #[test]
    fn a_building_and_a_cluster_are_described() {
        let city = city();
        let ids = SourceIds::of(&city);
        let facts = PickFacts {
            draw: 0,
            distance_m: 31.0,
            building_count: 2,
            bounds: ([0.0; 3], [10.0, 10.0, 12.0]),
            covered: &[],
            source_ids: &ids,
            city: &city,
            package_details: false,
        };
        let rows = describe(&facts).rows;
        let get = |rows: &[(String, String)], k: &str| {
            rows.iter()
                .find(|(name, _)| name == k)
                .map(|(_, v)| v.clone())
        };
        assert_eq!(get(&rows, "source id").as_deref(), Some("way/1"));
        assert_eq!(get(&rows, "levels").as_deref(), Some("4"));
        assert_eq!(get(&rows, "building:levels").as_deref(), Some("4"));
        // A package's viewer keeps only the source ids.
        let empty = City {
            buildings: Vec::new(),
            ..city.clone()
        };
        let rows = describe(&PickFacts {
            draw: 1,
            city: &empty,
            ..facts
        })
        .rows;
        assert_eq!(get(&rows, "source id").as_deref(), Some("way/22"));
        assert!(get(&rows, "tags").unwrap().contains("not loaded"));
        // ... and reads a building's levels and tags from the package on a pick.
        let mut picked = describe(&PickFacts {
            draw: 1,
            city: &empty,
            package_details: true,
            ..facts
        });
        assert_eq!(picked.details_pending, Some(1));
        assert!(get(&picked.rows, "tags").unwrap().contains("reading"));
        let details = BuildingDetails {
            parts: Vec::new(),
            tags: Tags::from([("building", "yes"), ("building:levels", "6")]),
        };
        let mut other = picked.clone();
        other.fill_details(0, Ok(details.clone()));
        assert_eq!(other, picked, "a read for another building changes nothing");
        picked.fill_details(1, Ok(details));
        assert_eq!(picked.details_pending, None);
        assert_eq!(get(&picked.rows, "levels").as_deref(), Some("6"));
        // The tag `building=yes` is listed after the id's own "building" row.
        assert!(
            picked
                .rows
                .iter()
                .any(|(k, v)| k == "building" && v == "yes"),
            "{:?}",
            picked.rows
        );
        assert_eq!(get(&picked.rows, "tags"), None);
        assert_eq!(
            picked.rows.last().map(|(k, _)| k.as_str()),
            Some("distance"),
            "the tags stand where the placeholder stood"
        );
        let mut failed = describe(&PickFacts {
            draw: 1,
            city: &empty,
            package_details: true,
            ..facts
        });
        let error = citywalk_scenes::package::PackageError::NoSuchBuilding { index: 1, count: 1 };
        failed.fill_details(1, Err(error.to_string()));
        assert!(get(&failed.rows, "tags").unwrap().contains("no building 1"));
        // A cluster: its node and its buildings.
        let rows = describe(&PickFacts {
            draw: 2 + 5,
            covered: &[0, 1],
            ..facts
        })
        .rows;
        assert_eq!(get(&rows, "cluster node").as_deref(), Some("5"));
        assert_eq!(get(&rows, "stands for").as_deref(), Some("2 buildings"));
    }
}
