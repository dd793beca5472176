//! Virtual occluders on real cities: every building gets occluders or a reason, never a panic;
//! the set's invariants hold; facades stay inside their buildings' silhouettes. The quality
//! numbers are printed (run with `--nocapture`), not asserted: they are benchmark results.

use std::path::Path;
use std::time::Instant;

use citywalk_preprocess::occluders::quality::{QualityParams, measure_city, summarise};
use citywalk_preprocess::occluders::{OccluderParams, build_occluders};
use citywalk_scenes::{LoadOptions, load_city};

fn check_city(path: &str, params: &OccluderParams) {
    let city = load_city(Path::new(path), &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{path}: {e}"));
    assert!(!city.buildings.is_empty(), "{path}: no buildings");
    let start = Instant::now();
    let set = build_occluders(&city, params);
    let seconds = start.elapsed().as_secs_f64();
    assert_eq!(set.check_invariants(), Ok(()));
    assert_eq!(set.per_building.len(), city.buildings.len());
    for (b, o) in city.buildings.iter().zip(&set.per_building) {
        assert_eq!(b.id, o.building);
        assert!(
            !o.occluder_range.is_empty() || o.reason_if_none.is_some(),
            "{}: no occluder and no reason",
            b.source_id
        );
        for occ in set.occluders_of(b.id) {
            assert!(
                occ.base_m >= b.base_m - 1e-3,
                "{}: occluder below the base",
                b.source_id
            );
            assert!(
                occ.z_m <= b.top_m + 1e-3,
                "{}: level above the top",
                b.source_id
            );
        }
    }
    let rows = measure_city(
        &city,
        &set,
        &QualityParams {
            views: 8,
            resolution_px: 64,
            ..QualityParams::default()
        },
    );
    let summary = summarise(&rows);
    // Facades inside their buildings cover (almost) no pixel outside the building's own
    // silhouette; rasterisation of coincident edges accounts for a little.
    assert!(summary.leak_fraction < 0.02, "{path}: leak {summary:?}");
    let failed = rows.iter().filter(|r| r.occluders == 0).count();
    eprintln!(
        "{path}: {} buildings ({} without occluders) in {:.2} s ({:.0} buildings/s)\n{summary:#?}",
        city.buildings.len(),
        failed,
        seconds,
        city.buildings.len() as f64 / seconds.max(1e-9)
    );
    let mut reasons: Vec<&str> = rows
        .iter()
        .filter_map(|r| r.reason_if_none.as_deref())
        .collect();
    reasons.sort_unstable();
    reasons.dedup();
    eprintln!("reasons: {reasons:?}");
}

const DEN_HAAG: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cityjson_denhaag/DenHaag_01.json"
);

#[test]
fn den_haag_cityjson_buildings_all_get_occluders_or_reasons() {
    check_city(DEN_HAAG, &OccluderParams::default());
}

#[test]
fn den_haag_with_the_benefit_rule_and_with_wall_selection() {
    check_city(
        DEN_HAAG,
        &OccluderParams {
            min_silhouette_gain_per_polygon: 0.0,
            ..OccluderParams::default()
        },
    );
    check_city(
        DEN_HAAG,
        &OccluderParams {
            select_walls: true,
            min_silhouette_gain_per_polygon: 0.05,
            ..OccluderParams::default()
        },
    );
}

#[test]
fn chelsea_osm_buildings_all_get_occluders_or_reasons() {
    check_city(
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenes/data/chelsea.osm.pbf"
        ),
        &OccluderParams::default(),
    );
}
