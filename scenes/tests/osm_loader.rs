//! The OSM PBF loader on real extracts (counts from the data folders' READMEs), on small
//! hand-made files (Simple 3D Buildings parts, multipolygons, bad buildings) and on corrupt
//! files (errors, never panics).

use std::path::Path;
use std::time::Instant;

use citywalk_scenes::load::osm;
use citywalk_scenes::{HeightSource, LoadError, LoadOptions, RejectReason};
use files::{temp_file, thread_cpu_ns};
use fuzz::fixed_runner;
use proptest::prelude::*;

#[path = "support/files.rs"]
mod files;
#[path = "support/fuzz.rs"]
mod fuzz;

const CHELSEA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/osm_nyc_chelsea/nyc.osm.pbf"
);
const PORTO: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/osm_porto_center/porto.osm.pbf"
);

/// A minimal OSM PBF writer (uncompressed blobs), enough to make small test files.
mod pbf {
    /// Tags as key/value pairs.
    pub type Tags = Vec<(&'static str, &'static str)>;
    /// Relation members: `(way id, role)`.
    pub type Members = Vec<(i64, &'static str)>;

    #[derive(Default)]
    pub struct Osm {
        /// `(id, lon°, lat°)`.
        pub nodes: Vec<(i64, f64, f64)>,
        pub ways: Vec<(i64, Tags, Vec<i64>)>,
        /// `(id, tags, [(way id, role)])`.
        pub relations: Vec<(i64, Tags, Members)>,
    }

    fn varint(out: &mut Vec<u8>, mut v: u64) {
        while v >= 0x80 {
            out.push((v as u8) | 0x80);
            v >>= 7;
        }
        out.push(v as u8);
    }
    fn zigzag(v: i64) -> u64 {
        ((v << 1) ^ (v >> 63)) as u64
    }
    fn key(out: &mut Vec<u8>, field: u32, wire: u32) {
        varint(out, u64::from(field << 3 | wire));
    }
    fn bytes(out: &mut Vec<u8>, field: u32, data: &[u8]) {
        key(out, field, 2);
        varint(out, data.len() as u64);
        out.extend_from_slice(data);
    }
    fn uint(out: &mut Vec<u8>, field: u32, v: u64) {
        key(out, field, 0);
        varint(out, v);
    }
    fn packed(out: &mut Vec<u8>, field: u32, values: impl IntoIterator<Item = u64>) {
        let mut data = Vec::new();
        for v in values {
            varint(&mut data, v);
        }
        if !data.is_empty() {
            bytes(out, field, &data);
        }
    }
    fn deltas(values: &[i64]) -> Vec<u64> {
        let mut prev = 0;
        values
            .iter()
            .map(|&v| {
                let d = v - prev;
                prev = v;
                zigzag(d)
            })
            .collect()
    }

    struct Strings(Vec<String>);
    impl Strings {
        fn id(&mut self, s: &str) -> u64 {
            if let Some(i) = self.0.iter().position(|x| x == s) {
                return i as u64;
            }
            self.0.push(s.to_string());
            (self.0.len() - 1) as u64
        }
    }

    fn blob(out: &mut Vec<u8>, kind: &str, data: &[u8]) {
        let mut blob = Vec::new();
        bytes(&mut blob, 1, data);
        uint(&mut blob, 2, data.len() as u64);
        let mut header = Vec::new();
        bytes(&mut header, 1, kind.as_bytes());
        uint(&mut header, 3, blob.len() as u64);
        out.extend_from_slice(&(header.len() as u32).to_be_bytes());
        out.extend_from_slice(&header);
        out.extend_from_slice(&blob);
    }

    impl Osm {
        pub fn encode(&self) -> Vec<u8> {
            let mut strings = Strings(vec![String::new()]);
            fn tags(strings: &mut Strings, msg: &mut Vec<u8>, t: &Tags) {
                let keys: Vec<u64> = t.iter().map(|(k, _)| strings.id(k)).collect();
                let vals: Vec<u64> = t.iter().map(|(_, v)| strings.id(v)).collect();
                packed(msg, 2, keys);
                packed(msg, 3, vals);
            }
            let mut nodes_group = Vec::new();
            for &(id, lon, lat) in &self.nodes {
                let mut n = Vec::new();
                uint(&mut n, 1, zigzag(id));
                uint(&mut n, 8, zigzag((lat * 1e7).round() as i64));
                uint(&mut n, 9, zigzag((lon * 1e7).round() as i64));
                bytes(&mut nodes_group, 1, &n);
            }
            let mut ways_group = Vec::new();
            for (id, t, refs) in &self.ways {
                let mut w = Vec::new();
                uint(&mut w, 1, *id as u64);
                tags(&mut strings, &mut w, t);
                packed(&mut w, 8, deltas(refs));
                bytes(&mut ways_group, 3, &w);
            }
            let mut rel_group = Vec::new();
            let mut roles = Vec::new();
            for (id, t, members) in &self.relations {
                let mut r = Vec::new();
                uint(&mut r, 1, *id as u64);
                tags(&mut strings, &mut r, t);
                roles.push(members.iter().map(|m| m.1).collect::<Vec<_>>());
                let ids: Vec<i64> = members.iter().map(|m| m.0).collect();
                rel_group.push((r, ids));
            }
            let mut rel_bytes = Vec::new();
            for ((mut r, ids), role_names) in rel_group.into_iter().zip(roles) {
                let role_ids: Vec<u64> = role_names.iter().map(|s| strings.id(s)).collect();
                packed(&mut r, 8, role_ids);
                packed(&mut r, 9, deltas(&ids));
                packed(&mut r, 10, ids.iter().map(|_| 1));
                bytes(&mut rel_bytes, 4, &r);
            }
            let mut table = Vec::new();
            for s in &strings.0 {
                bytes(&mut table, 1, s.as_bytes());
            }
            let mut block = Vec::new();
            bytes(&mut block, 1, &table);
            for group in [nodes_group, ways_group, rel_bytes] {
                if !group.is_empty() {
                    bytes(&mut block, 2, &group);
                }
            }
            let mut header = Vec::new();
            bytes(&mut header, 4, b"OsmSchema-V0.6");
            let mut out = Vec::new();
            blob(&mut out, "OSMHeader", &header);
            blob(&mut out, "OSMData", &block);
            out
        }
    }
}

/// A square of `size_deg` at `(lon, lat)` as nodes `first..first+4`, and the closed way's refs.
fn square(osm: &mut pbf::Osm, first: i64, lon: f64, lat: f64, size_deg: f64) -> Vec<i64> {
    let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
    for (i, (dx, dy)) in corners.iter().enumerate() {
        osm.nodes
            .push((first + i as i64, lon + dx * size_deg, lat + dy * size_deg));
    }
    vec![first, first + 1, first + 2, first + 3, first]
}

fn load_bytes(name: &str, bytes: &[u8]) -> Result<citywalk_scenes::City, LoadError> {
    let path = temp_file(name, bytes);
    osm::load(&path, &LoadOptions::default())
}

#[test]
fn chelsea_counts_match_the_readme() {
    let start = Instant::now();
    let cpu = thread_cpu_ns();
    let city = osm::load(Path::new(CHELSEA), &LoadOptions::default()).unwrap();
    let elapsed = start.elapsed();
    let cpu_ms = thread_cpu_ns().saturating_sub(cpu) as f64 * 1e-6;
    let r = &city.report;
    println!("Chelsea PBF: {r} in {elapsed:.2?} (CPU {cpu_ms:.1} ms)");
    assert_eq!(r.buildings_found, 1525, "{r}");
    assert_eq!(r.parts_found, 43, "{r}");
    assert_eq!(r.buildings_with_height, 1514, "{r}");
    assert!(r.is_balanced(), "{r}");
    assert_eq!(r.buildings_loaded, city.buildings.len());
    city.check_invariants().unwrap();
    // Every part found in the file is attached to one building, except the six whose
    // building outline lies beyond the extract's edge (dropped with a warning each).
    let attached: usize = city
        .buildings
        .iter()
        .map(|b| {
            b.parts
                .iter()
                .filter(|p| p.source_id != b.source_id)
                .count()
        })
        .sum();
    let orphans = r
        .warnings
        .iter()
        .filter(|w| w.message.contains("inside no building"))
        .count();
    assert_eq!((attached, orphans), (37, 6));
    assert!(
        r.streets_loaded > 0 && r.streets_loaded == city.streets.len(),
        "{r}"
    );
    assert!(city.streets.iter().all(|s| s.line.0.len() >= 2));
    // The frame is at the centre of the buildings: the city's bounds straddle the origin.
    let (lo, hi) = city.bounds().unwrap();
    assert!(lo.x < 0.0 && hi.x > 0.0 && lo.y < 0.0 && hi.y > 0.0);
    assert!((lo.x + hi.x).abs() < 1.0 && (lo.y + hi.y).abs() < 1.0);
    // README: height min/median/max = 2.7 / 14.2 / 69.4 m.
    let tallest = city.buildings.iter().map(|b| b.top_m).fold(0.0, f32::max);
    assert!((tallest - 69.4).abs() < 0.05, "{tallest}");
    // Ground areas (issue 16), by class; one multipolygon reaches beyond the extract.
    let mut by_class = std::collections::BTreeMap::new();
    for g in &city.ground_areas {
        *by_class.entry(g.class.name()).or_insert(0) += 1;
    }
    println!("Chelsea ground areas: {by_class:?}");
    let expected = [("grass", 1), ("other", 5), ("park", 11), ("paved", 2)];
    assert_eq!(by_class, expected.into_iter().collect(), "{r}");
    assert_eq!(r.ground_areas_found, 20, "{r}");
    assert_eq!(r.ground_areas_rejected[0].source_id, "relation/2389611");
}

#[test]
fn porto_counts_match_the_readme() {
    let start = Instant::now();
    let cpu = thread_cpu_ns();
    let city = osm::load(Path::new(PORTO), &LoadOptions::default()).unwrap();
    let elapsed = start.elapsed();
    let cpu_ms = thread_cpu_ns().saturating_sub(cpu) as f64 * 1e-6;
    let r = &city.report;
    println!("Porto PBF: {r} in {elapsed:.2?} (CPU {cpu_ms:.1} ms)");
    assert_eq!(r.buildings_found, 11_404, "{r}");
    assert_eq!(r.parts_found, 61, "{r}");
    assert!(r.is_balanced(), "{r}");
    city.check_invariants().unwrap();
    assert_eq!(r.buildings_with_height, 5, "{r}");
    // README: building:levels on 667 buildings; one of them (way/226933218, levels 2 from
    // min_level 2) has zero height and is rejected.
    assert_eq!(r.rejected.len(), 1, "{:?}", r.rejected);
    assert_eq!(r.rejected[0].source_id, "way/226933218");
    let tagged = |b: &&citywalk_scenes::Building, k: &str| b.tags.contains_key(k);
    let with_levels = city
        .buildings
        .iter()
        .filter(|b| tagged(b, "building:levels"))
        .count();
    assert_eq!(with_levels, 666);
    let levels_only = city
        .buildings
        .iter()
        .filter(|b| tagged(b, "building:levels") && !tagged(b, "height"))
        .count();
    assert_eq!(
        r.buildings_estimated_height,
        r.buildings_loaded - r.buildings_with_height - levels_only,
        "{r}"
    );
    assert!(
        city.buildings
            .iter()
            .filter(|b| b.parts.len() == 1 && tagged(b, "building:levels") && !tagged(b, "height"))
            .all(|b| b.height_source == HeightSource::Levels)
    );
}

#[test]
fn parts_replace_the_outline() {
    // Simple 3D Buildings: a 20 m building outline with two parts inside (a low podium and a
    // tower), and a second building without parts.
    let mut osm = pbf::Osm::default();
    let d = 0.0002; // about 17 m of longitude, 22 m of latitude here
    let outline = square(&mut osm, 1, 8.0, 47.0, d);
    let podium = {
        let r = square(&mut osm, 11, 8.0, 47.0, d);
        // Shrink the podium to the southern half: move its northern nodes.
        for n in &mut osm.nodes {
            if n.0 == 13 || n.0 == 14 {
                n.2 = 47.0 + d * 0.5;
            }
        }
        r
    };
    let tower = square(&mut osm, 21, 8.0 + d * 0.25, 47.0 + d * 0.55, d * 0.4);
    let other = square(&mut osm, 31, 8.01, 47.0, d);
    osm.ways.push((
        100,
        vec![("building", "yes"), ("height", "30"), ("name", "Tower")],
        outline,
    ));
    osm.ways.push((
        101,
        vec![("building:part", "yes"), ("height", "8 m")],
        podium,
    ));
    osm.ways.push((
        102,
        vec![
            ("building:part", "yes"),
            ("height", "98'5\""),
            ("min_height", "8"),
        ],
        tower,
    ));
    osm.ways.push((
        103,
        vec![("building", "house"), ("building:levels", "2")],
        other,
    ));
    // Through the format dispatch, as the CLI loads it.
    let path = temp_file("parts.osm.pbf", &osm.encode());
    let city = citywalk_scenes::load_city(&path, &LoadOptions::default()).unwrap();
    let r = &city.report;
    assert_eq!(
        (r.buildings_found, r.parts_found, r.buildings_loaded),
        (2, 2, 2),
        "{r}"
    );
    city.check_invariants().unwrap();
    let tower = city
        .buildings
        .iter()
        .find(|b| b.source_id == "way/100")
        .unwrap();
    assert_eq!(tower.parts.len(), 2);
    let mut ids: Vec<&str> = tower.parts.iter().map(|p| p.source_id.as_str()).collect();
    ids.sort_unstable();
    assert_eq!(ids, ["way/101", "way/102"]);
    let top = tower
        .parts
        .iter()
        .find(|p| p.source_id == "way/102")
        .unwrap();
    assert_eq!(top.base_m, 8.0);
    assert!((top.top_m - 30.0).abs() < 0.01, "{}", top.top_m);
    assert_eq!(
        (tower.base_m, tower.height_source),
        (0.0, HeightSource::Tagged)
    );
    // The building keeps its whole outline as footprint; the parts are smaller.
    let podium = tower
        .parts
        .iter()
        .find(|p| p.source_id == "way/101")
        .unwrap();
    use geo::Area;
    assert!(podium.footprint.unsigned_area() < 0.6 * tower.footprint.unsigned_area());
    let house = city
        .buildings
        .iter()
        .find(|b| b.source_id == "way/103")
        .unwrap();
    assert_eq!(house.parts.len(), 1);
    assert_eq!(
        (house.top_m, house.height_source),
        (6.0, HeightSource::Levels)
    );
    assert_eq!(house.tags.get("building"), Some("house"));
}

#[test]
fn orphan_part_is_dropped_with_a_warning() {
    let mut osm = pbf::Osm::default();
    let a = square(&mut osm, 1, 8.0, 47.0, 0.0002);
    let b = square(&mut osm, 11, 8.01, 47.0, 0.0002);
    osm.ways.push((1, vec![("building", "yes")], a));
    osm.ways
        .push((2, vec![("building:part", "yes"), ("height", "5")], b));
    let city = load_bytes("orphan.osm.pbf", &osm.encode()).unwrap();
    let r = &city.report;
    assert_eq!(
        (r.buildings_found, r.parts_found, r.buildings_loaded),
        (1, 1, 1),
        "{r}"
    );
    assert!(r.is_balanced());
    assert_eq!(city.buildings[0].parts.len(), 1);
    assert_eq!(city.buildings[0].parts[0].source_id, "way/1");
    assert!(
        r.warnings.iter().any(|w| w.source_id == "way/2"),
        "{:?}",
        r.warnings
    );
}

#[test]
fn multipolygon_rings_are_joined_from_split_ways() {
    // An outer square split over two ways (one reversed) with a hole, plus a relation whose
    // outer ring stays open.
    let mut osm = pbf::Osm::default();
    let outer = square(&mut osm, 1, 8.0, 47.0, 0.001);
    let hole = square(&mut osm, 11, 8.0004, 47.0004, 0.0002);
    osm.ways.push((10, vec![], outer[0..3].to_vec()));
    let mut back = outer[2..5].to_vec();
    back.reverse();
    osm.ways.push((11, vec![], back));
    osm.ways.push((12, vec![], hole));
    osm.relations.push((
        500,
        vec![
            ("type", "multipolygon"),
            ("building", "yes"),
            ("height", "12"),
        ],
        vec![(10, "outer"), (11, "outer"), (12, "inner")],
    ));
    let open = square(&mut osm, 21, 8.01, 47.0, 0.001);
    osm.ways.push((20, vec![], open[0..3].to_vec()));
    osm.relations.push((
        501,
        vec![("type", "multipolygon"), ("building", "yes")],
        vec![(20, "outer")],
    ));
    let city = load_bytes("multipolygon.osm.pbf", &osm.encode()).unwrap();
    let r = &city.report;
    assert_eq!((r.buildings_found, r.buildings_loaded), (2, 1), "{r}");
    let b = &city.buildings[0];
    assert_eq!(b.source_id, "relation/500");
    assert_eq!(b.footprint.0.len(), 1);
    assert_eq!(b.footprint.0[0].interiors().len(), 1);
    assert_eq!(r.rejected[0].source_id, "relation/501");
    assert!(
        matches!(&r.rejected[0].reason, RejectReason::InvalidGeometry(m) if m.contains("open")),
        "{:?}",
        r.rejected[0]
    );
}

#[test]
fn bad_buildings_are_rejected_and_the_rest_load() {
    let mut osm = pbf::Osm::default();
    let good = square(&mut osm, 1, 8.0, 47.0, 0.0002);
    osm.ways.push((1, vec![("building", "yes")], good.clone()));
    osm.ways.push((
        2,
        vec![("building", "yes"), ("height", "99999")],
        good.clone(),
    ));
    osm.ways
        .push((3, vec![("building", "yes"), ("height", "-5")], good.clone()));
    // Missing node 999.
    osm.ways
        .push((4, vec![("building", "yes")], vec![1, 2, 999, 4, 1]));
    // Not closed.
    osm.ways
        .push((5, vec![("building", "yes")], vec![1, 2, 3, 4]));
    // Fewer than 3 distinct points.
    osm.ways.push((6, vec![("building", "yes")], vec![1, 2, 1]));
    // Zero area: three collinear nodes.
    osm.nodes.push((50, 8.1, 47.0));
    osm.nodes.push((51, 8.1001, 47.0));
    osm.nodes.push((52, 8.1002, 47.0));
    osm.ways
        .push((7, vec![("building", "yes")], vec![50, 51, 52, 50]));
    // A ring that runs three times around the same square: no repair keeps its area.
    let mut thrice = Vec::new();
    for _ in 0..3 {
        thrice.extend_from_slice(&good[..4]);
    }
    thrice.push(good[0]);
    osm.ways.push((8, vec![("building", "yes")], thrice));
    // building=no is not a building at all.
    osm.ways.push((9, vec![("building", "no")], good.clone()));
    let city = load_bytes("bad.osm.pbf", &osm.encode()).unwrap();
    let r = &city.report;
    assert_eq!(
        (r.buildings_found, r.buildings_loaded),
        (8, 1),
        "{r}: {:?}",
        r.rejected
    );
    assert!(r.is_balanced());
    let reason = |id: &str| {
        r.rejected
            .iter()
            .find(|x| x.source_id == id)
            .map(|x| x.reason.clone())
            .unwrap_or_else(|| panic!("{id} not rejected"))
    };
    assert!(matches!(reason("way/2"), RejectReason::AbsurdHeight(_)));
    assert!(matches!(reason("way/3"), RejectReason::AbsurdHeight(_)));
    assert!(matches!(reason("way/4"), RejectReason::MissingGeometry(m) if m.contains("999")));
    assert!(matches!(reason("way/5"), RejectReason::InvalidGeometry(_)));
    assert_eq!(reason("way/6"), RejectReason::TooFewPoints);
    assert_eq!(reason("way/7"), RejectReason::ZeroArea);
    assert_eq!(reason("way/8"), RejectReason::SelfIntersection);
    for x in &r.rejected {
        assert!(x.to_string().contains("bad.osm.pbf"), "{x}");
    }
}

#[test]
fn malformed_files_are_errors_naming_the_file() {
    let chelsea = std::fs::read(CHELSEA).unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty.osm.pbf", Vec::new()),
        (
            "text.osm.pbf",
            b"this is not a protocol buffer, just text\n".to_vec(),
        ),
        ("truncated.osm.pbf", chelsea[..chelsea.len() / 2].to_vec()),
        ("header-only.osm.pbf", chelsea[..200].to_vec()),
    ];
    for (name, bytes) in cases {
        let err = load_bytes(name, &bytes).expect_err(name);
        assert!(err.to_string().contains(name), "{name}: {err}");
        assert!(matches!(err, LoadError::Malformed { .. }), "{name}: {err}");
    }
    let missing = osm::load(Path::new("/nonexistent/x.osm.pbf"), &LoadOptions::default());
    assert!(matches!(missing, Err(LoadError::Io { .. })));
}

/// Loads `bytes` and checks the outcome: an error, or a balanced report with a valid city.
fn check_outcome(path: &Path) -> Result<(), TestCaseError> {
    match osm::load(path, &LoadOptions::default()) {
        Err(e) => {
            prop_assert!(e.to_string().contains(&*path.to_string_lossy()), "{e}");
        }
        Ok(city) => {
            prop_assert!(city.report.is_balanced(), "{}", city.report);
            prop_assert!(city.check_invariants().is_ok());
        }
    }
    Ok(())
}

#[test]
fn corrupt_pbf_never_panics() {
    let mut osm = pbf::Osm::default();
    let a = square(&mut osm, 1, 8.0, 47.0, 0.0002);
    let b = square(&mut osm, 11, 8.00005, 47.00005, 0.0001);
    osm.ways
        .push((1, vec![("building", "yes"), ("height", "20")], a.clone()));
    osm.ways
        .push((2, vec![("building:part", "yes"), ("height", "25")], b));
    osm.ways
        .push((3, vec![("highway", "residential")], a[..3].to_vec()));
    osm.relations.push((
        4,
        vec![("type", "multipolygon"), ("building", "yes")],
        vec![(1, "outer")],
    ));
    let small = osm.encode();
    let chelsea = std::fs::read(CHELSEA).unwrap();
    let mut runner = fixed_runner(96, 7);
    let strategy = (
        any::<bool>(),
        prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        any::<prop::sample::Index>(),
    );
    runner
        .run(&strategy, |(use_chelsea, flips, cut)| {
            let mut bytes = if use_chelsea {
                chelsea[..cut.index(chelsea.len())].to_vec()
            } else {
                small.clone()
            };
            if !bytes.is_empty() {
                for (at, value) in &flips {
                    let i = at.index(bytes.len());
                    bytes[i] ^= value | 1;
                }
            }
            let path = temp_file("fuzz.osm.pbf", &bytes);
            check_outcome(&path)
        })
        .unwrap();
    std::fs::remove_file(temp_file("fuzz.osm.pbf", b"")).ok();
}

/// Issue 14 case 9: one changed block-type byte of `nyc.osm.pbf` loaded 1,520 of 1,525
/// buildings with exit 0, only the warning count moving. A type one byte from `OSMData` is
/// now an error naming the block; a block of a truly unknown type is skipped (as the format
/// asks) with a warning naming it.
#[test]
fn a_damaged_or_unknown_block_is_named() {
    let bytes = std::fs::read(CHELSEA).unwrap();
    // Blocks: 0 the header, 1 nodes, 2 and 3 more data.
    let data_blocks: Vec<usize> = (bytes.windows(7).enumerate())
        .filter(|(_, w)| *w == b"OSMData")
        .map(|(i, _)| i)
        .collect();
    assert_eq!(data_blocks.len(), 3);
    let at = data_blocks[2];
    let mut damaged = bytes.clone();
    damaged[at + 4] = b'b';
    let path = temp_file("damaged.osm.pbf", &damaged);
    let err = osm::load(&path, &LoadOptions::default()).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("damaged.osm.pbf") && text.contains("block 3"),
        "{text}"
    );
    assert!(text.contains("\"OSMDbta\""), "{text}");

    let mut unknown = bytes;
    let at = data_blocks[1];
    unknown[at..at + 3].copy_from_slice(b"XYZ");
    let path = temp_file("unknown.osm.pbf", &unknown);
    let city = osm::load(&path, &LoadOptions::default()).unwrap();
    let r = &city.report;
    assert_eq!(r.buildings_found, 1520, "{r}");
    let skipped: Vec<String> = r.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        skipped
            .iter()
            .any(|w| w.contains("block 2 (at byte") && w.contains("\"XYZData\" skipped")),
        "{skipped:?}"
    );
}

/// Issue 14: a way repeated in one OSM file (and a building repeated across two extracts) was
/// kept twice without a warning. The repeat is dropped with a warning naming `way/ID`, and the
/// counts are those of the distinct buildings.
#[test]
fn issue14_small_duplicate_osm_id_is_dropped_with_a_warning() {
    let mut osm = pbf::Osm::default();
    let a = square(&mut osm, 1, 8.0, 47.0, 0.0002);
    let b = square(&mut osm, 10, 8.001, 47.0, 0.0002);
    let tags: pbf::Tags = vec![("building", "yes"), ("height", "12")];
    osm.ways.push((100, tags.clone(), a.clone()));
    osm.ways.push((200, tags.clone(), b));
    osm.ways.push((100, tags, a));
    let path = temp_file("dup-way.osm.pbf", &osm.encode());
    let city =
        citywalk_scenes::load_cities(std::slice::from_ref(&path), &LoadOptions::default()).unwrap();
    let ids: Vec<&str> = city
        .buildings
        .iter()
        .map(|b| b.source_id.as_str())
        .collect();
    assert_eq!(ids, ["way/100", "way/200"]);
    let r = &city.report;
    assert_eq!((r.buildings_found, r.buildings_loaded), (2, 2), "{r}");
    assert!(r.is_balanced(), "{r}");
    city.check_invariants().unwrap();
    let warned: Vec<_> = r
        .warnings
        .iter()
        .filter(|w| w.message.contains("duplicate dropped"))
        .collect();
    assert_eq!(warned.len(), 1, "{:?}", r.warnings);
    assert_eq!(warned[0].source_id, "way/100");
    assert!(
        warned[0].message.contains("earlier in this file"),
        "{}",
        warned[0]
    );

    // The same extract under another name (overlapping extracts): every building once.
    let copy = temp_file("dup-way-copy.osm.pbf", &std::fs::read(&path).unwrap());
    let city =
        citywalk_scenes::load_cities(&[path.clone(), copy], &LoadOptions::default()).unwrap();
    assert_eq!(city.buildings.len(), 2);
    assert_eq!(city.report.buildings_found, 2, "{}", city.report);
    let dropped = city
        .report
        .warnings
        .iter()
        .filter(|w| w.message.contains("duplicate dropped"))
        .count();
    // The repeat inside the first file, then all three ways of the copy.
    assert_eq!(dropped, 4, "{:?}", city.report.warnings);
}

/// The area (m²) of a lon/lat ring in the city's frame, for expected ground-area sizes.
fn local_area_m2(city: &citywalk_scenes::City, ring: &[(f64, f64)]) -> f64 {
    let local: Vec<glam::DVec3> = ring
        .iter()
        .map(|&(lon, lat)| city.frame.to_local(glam::DVec3::new(lon, lat, 0.0)))
        .collect();
    let twice: f64 = local
        .iter()
        .zip(local.iter().cycle().skip(1))
        .map(|(a, b)| a.x * b.y - b.x * a.y)
        .sum();
    0.5 * twice.abs()
}

/// The corners of [`square`]'s ring, as lon/lat.
fn square_corners(lon: f64, lat: f64, size_deg: f64) -> Vec<(f64, f64)> {
    [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
        .iter()
        .map(|(dx, dy)| (lon + dx * size_deg, lat + dy * size_deg))
        .collect()
}

/// Issue 16: water, a park (a multipolygon with a hole), a square and a parking lot load as
/// ground areas of their class; a ground area that cannot be built is rejected with its id; a
/// building tagged with `landuse` stays a building only; a plaza (`highway=pedestrian` +
/// `area=yes`) is an area, not a street line; an underground car park is no ground area.
#[test]
fn ground_areas_load_by_class() {
    use citywalk_scenes::GroundClass;
    let mut osm = pbf::Osm::default();
    let d = 0.0002;
    let house = square(&mut osm, 1, 8.0, 47.0, d);
    osm.ways.push((
        1,
        vec![("building", "yes"), ("landuse", "residential")],
        house,
    ));
    let water = square(&mut osm, 11, 8.001, 47.0, 0.001);
    osm.ways.push((2, vec![("natural", "water")], water));
    let plaza = square(&mut osm, 21, 8.0, 47.001, d);
    osm.ways.push((
        3,
        vec![
            ("highway", "pedestrian"),
            ("area", "yes"),
            ("name", "Plaza"),
        ],
        plaza,
    ));
    let parking = square(&mut osm, 31, 8.0, 47.002, d);
    osm.ways
        .push((4, vec![("amenity", "parking")], parking.clone()));
    osm.ways.push((
        5,
        vec![("amenity", "parking"), ("parking", "underground")],
        parking,
    ));
    // A park: a multipolygon whose outer ring is split over two untagged ways, with a hole.
    let outer = square(&mut osm, 41, 8.003, 47.0, 0.001);
    let hole = square(&mut osm, 51, 8.0034, 47.0004, 0.0002);
    osm.ways.push((40, vec![], outer[0..3].to_vec()));
    osm.ways.push((41, vec![], outer[2..5].to_vec()));
    osm.ways.push((42, vec![], hole));
    osm.relations.push((
        600,
        vec![("type", "multipolygon"), ("leisure", "park")],
        vec![(40, "outer"), (41, "outer"), (42, "inner")],
    ));
    // Malformed: an open grass way, and a forest relation whose member is not in the file.
    let grass = square(&mut osm, 61, 8.0, 47.003, d);
    osm.ways
        .push((6, vec![("landuse", "grass")], grass[0..4].to_vec()));
    osm.relations.push((
        601,
        vec![("type", "multipolygon"), ("landuse", "forest")],
        vec![(999, "outer")],
    ));
    let city = load_bytes("ground.osm.pbf", &osm.encode()).unwrap();
    let r = &city.report;
    assert!(r.is_balanced(), "{r}");
    city.check_invariants().unwrap();
    assert_eq!((r.buildings_found, r.buildings_loaded), (1, 1), "{r}");
    assert_eq!(
        (r.ground_areas_found, r.ground_areas_loaded),
        (6, 4),
        "{r}: {:?}",
        r.ground_areas_rejected
    );
    let area = |id: &str| {
        city.ground_areas
            .iter()
            .find(|g| g.source_id == id)
            .unwrap_or_else(|| panic!("{id} not loaded: {:?}", city.ground_areas))
    };
    let close = |got: f64, want: f64| (got - want).abs() < 1e-6 * want;
    use geo::Area;
    let water_m2 = local_area_m2(&city, &square_corners(8.001, 47.0, 0.001));
    assert_eq!(area("way/2").class, GroundClass::Water);
    assert!(close(area("way/2").polygon.unsigned_area(), water_m2));
    assert!(water_m2 > 8000.0 && water_m2 < 9000.0, "{water_m2}");
    assert_eq!(area("way/3").class, GroundClass::Paved);
    assert_eq!(area("way/4").class, GroundClass::Paved);
    let park = area("relation/600");
    assert_eq!(park.class, GroundClass::Park);
    assert_eq!(park.polygon.0.len(), 1);
    assert_eq!(park.polygon.0[0].interiors().len(), 1);
    let park_m2 = local_area_m2(&city, &square_corners(8.003, 47.0, 0.001))
        - local_area_m2(&city, &square_corners(8.0034, 47.0004, 0.0002));
    assert!(close(park.polygon.unsigned_area(), park_m2));
    // The plaza is no street; the building is no ground area.
    assert!(city.streets.is_empty(), "{:?}", city.streets);
    assert_eq!(r.streets_found, 0);
    assert!(city.ground_areas.iter().all(|g| g.source_id != "way/1"));
    assert_eq!(city.buildings[0].source_id, "way/1");
    // Rejections name the file, the id and the reason.
    let reason = |id: &str| {
        r.ground_areas_rejected
            .iter()
            .find(|x| x.source_id == id)
            .map(|x| x.reason.clone())
            .unwrap_or_else(|| panic!("{id} not rejected"))
    };
    assert!(matches!(reason("way/6"), RejectReason::InvalidGeometry(m) if m.contains("closed")));
    assert!(
        matches!(reason("relation/601"), RejectReason::MissingGeometry(m) if m.contains("999"))
    );
    assert!(
        r.ground_areas_rejected
            .iter()
            .all(|x| x.file.ends_with("ground.osm.pbf"))
    );
}
