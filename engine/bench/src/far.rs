//! Far views: frames whose camera is farther from the city's centre than the city's diameter
//! ([`citywalk_scenes::city_sphere::CitySphere`]), and the share of the full-detail triangles a mode draws there.
//!
//! This work is based on Chang et al. 2008 §9: far from the city a legible simplification draws
//! a small share of the polygons (Fig. 13(c): 5.6 % of the original's; Fig. 14(b): "drastic
//! simplifications for view points that are far away from the city model"). Every frame records
//! its distance and share ([`FrameRecord::distance_diameters`], [`FrameRecord::triangle_share`]);
//! [`FarShare::of`] sums them up per scene × path × mode, for any path.

use std::fmt::Write as _;

use citywalk_runtime::camera::Camera;
use serde::Serialize;

use crate::bound::BoundCheck;
use crate::output::BenchReport;
use crate::run::{BenchScene, FrameRecord};

/// A frame is far when its camera is more than this many city diameters from the centre: every
/// building is then at least half a diameter away.
pub const FAR_DIAMETERS: f64 = 1.0;

/// How far `camera` is from the centre of `scene`'s city, in diameters of its sphere
/// ([`BenchScene::sphere`]).
pub fn distance_in_diameters(scene: &BenchScene, camera: &Camera) -> f64 {
    f64::from(scene.sphere.distance_in_diameters(camera.position))
}

/// `triangles` ÷ the triangles of every building of `scene` at full detail (what brute force
/// draws); 0 for a scene without triangles.
pub fn triangle_share(scene: &BenchScene, triangles: u64) -> f64 {
    match scene.drawable.buildings.triangle_count {
        0 => 0.0,
        full => triangles as f64 / full as f64,
    }
}

/// What a scene × path × mode drew in its far frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FarShare {
    /// Frames farther than [`FAR_DIAMETERS`].
    pub frames: usize,
    /// Mean over those frames of the triangles drawn ÷ the full-detail triangles.
    pub mean: f64,
    /// The largest share of one of those frames.
    pub max: f64,
    /// The LOD bound over those frames, as the entry's `bound_violations` ([`crate::bound`]):
    /// of their pixels differing from brute force, the share beyond the bound.
    pub bound_violations: f64,
    /// The largest share of one of those frames.
    pub bound_violations_max: f64,
}

impl FarShare {
    /// The far frames among `records` (one scene × path × mode), `None` when there are none.
    pub fn of<'a>(records: impl IntoIterator<Item = &'a FrameRecord>) -> Option<FarShare> {
        let far: Vec<&FrameRecord> = records
            .into_iter()
            .filter(|r| r.distance_diameters > FAR_DIAMETERS)
            .collect();
        if far.is_empty() {
            return None;
        }
        Some(FarShare {
            frames: far.len(),
            mean: far.iter().map(|r| r.triangle_share).sum::<f64>() / far.len() as f64,
            max: far.iter().map(|r| r.triangle_share).fold(0.0, f64::max),
            bound_violations: far
                .iter()
                .map(|r| r.bound_check())
                .sum::<BoundCheck>()
                .share(),
            bound_violations_max: far
                .iter()
                .map(|r| r.bound_check().share())
                .fold(0.0, f64::max),
        })
    }
}

/// The far-view table of `summary.md`: one row per entry with far frames (nothing when no entry
/// has any).
pub fn far_table(out: &mut String, report: &BenchReport) {
    let rows: Vec<_> = report
        .entries
        .iter()
        .filter_map(|e| Some((e, e.far_triangle_share.as_ref()?)))
        .collect();
    if rows.is_empty() {
        return;
    }
    let _ = write!(
        out,
        "\nFar views (Chang et al. 2008 §9, Fig. 14): frames whose camera is more than \
         {FAR_DIAMETERS} city diameter from the centre of the buildings' bounding box; triangles \
         drawn ÷ the full-detail triangles (brute force), and the LOD bound in those frames.\n\n\
         | scene | path | mode | far frames | triangles ÷ full (mean / max) | \
         bound violations (far frames / worst) | false culls (path) |\n\
         |---|---|---|---:|---:|---:|---:|\n"
    );
    for (e, far) in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {:.2} % / {:.2} % | {:.3} % / {:.3} % | {} |",
            e.scene,
            e.path,
            e.mode,
            far.frames,
            100.0 * far.mean,
            100.0 * far.max,
            100.0 * far.bound_violations,
            100.0 * far.bound_violations_max,
            e.false_culls,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::summarise;
    use crate::output::tests::{record, report_of};

    /// A frame of `mode` at `distance` diameters drawing `share` of the full triangles, with
    /// `differing` pixels off brute force, `beyond` of them beyond the bound.
    fn frame(mode: &str, i: usize, distance: f64, share: f64, bound: (u64, u64)) -> FrameRecord {
        let mut r = record(mode, i, 1.0, 0);
        r.path = "overview".into();
        r.distance_diameters = distance;
        r.triangle_share = share;
        (r.differing_px, r.beyond_bound_px) = bound;
        r
    }

    #[test]
    fn only_frames_beyond_one_diameter_count() {
        let records = [
            frame("lod", 0, 3.0, 0.02, (100, 0)),
            frame("lod", 1, 1.5, 0.04, (300, 3)),
            // Exactly one diameter away is not far; nearer frames draw more and do not count.
            frame("lod", 2, 1.0, 0.50, (1000, 900)),
            frame("lod", 3, 0.8, 0.90, (1000, 900)),
            frame("lod", 4, 2.0, 0.03, (0, 0)),
        ];
        let far = FarShare::of(&records).expect("far frames");
        assert_eq!(far.frames, 3);
        assert!((far.mean - 0.03).abs() < 1e-12, "{far:?}");
        assert_eq!(far.max, 0.04);
        // 3 of the 400 differing pixels of the far frames; the worst frame 1 %.
        assert_eq!(far.bound_violations, 3.0 / 400.0);
        assert_eq!(far.bound_violations_max, 0.01);
        assert_eq!(FarShare::of(&records[2..4]), None);
    }

    #[test]
    fn reaches_the_json_and_the_summary_per_entry() {
        let records = [
            frame("brute", 0, 2.0, 1.0, (0, 0)),
            frame("lod", 0, 2.0, 0.045, (10, 0)),
            frame("brute", 1, 0.5, 1.0, (0, 0)),
            frame("lod", 1, 0.5, 0.4, (10, 0)),
            record("lod", 0, 1.0, 0),
        ];
        let entries = summarise(&records);
        let far = |i: usize| entries[i].far_triangle_share.clone();
        assert_eq!(far(0).map(|f| (f.frames, f.mean)), Some((1, 1.0)));
        assert_eq!(far(1).map(|f| (f.frames, f.max)), Some((1, 0.045)));
        // The street path of `record` is never far.
        assert_eq!(entries[2].path, "street");
        assert_eq!(far(2), None);
        let report = report_of(entries);
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["entries"][1]["far_triangle_share"]["mean"], 0.045);
        assert!(json["entries"][2]["far_triangle_share"].is_null());
        let md = crate::output::summary_markdown(&report);
        assert!(md.contains("Far views"), "{md}");
        assert!(
            md.contains("| s | overview | lod | 1 | 4.50 % / 4.50 % | 0.000 % / 0.000 % | 0 |"),
            "{md}"
        );
        let table = md.split("Far views").nth(1).expect("far table");
        let rows: Vec<&str> = table.lines().filter(|l| l.starts_with("| s |")).collect();
        assert_eq!(rows.len(), 2, "{table}");
        // No far frame anywhere: no table.
        let near = report_of(summarise(&records[2..]));
        assert!(!crate::output::summary_markdown(&near).contains("Far views"));
    }
}
