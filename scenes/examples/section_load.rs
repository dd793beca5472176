use citywalk_scenes::package::{PackageFile, SectionKind};
use std::time::Instant;
fn rss_mb() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap();
    let l = s.lines().find(|l| l.starts_with("VmRSS")).unwrap();
    l.split_whitespace().nth(1).unwrap().parse::<f64>().unwrap() / 1024.0
}
fn main() {
    let p = std::env::args().nth(1).unwrap();
    let t = Instant::now();
    let f = PackageFile::open(p.as_ref()).unwrap();
    let runtime = std::env::args().nth(2).is_some();
    println!(
        "open+verify {:.2}s rss {:.0}",
        t.elapsed().as_secs_f64(),
        rss_mb()
    );
    for e in f.sections() {
        println!(
            "section {:?} {:.1} MB",
            SectionKind::from_u32(e.kind).map(|k| k.name()),
            e.length as f64 / 1e6
        );
    }
    macro_rules! one {
        ($k:expr, $t:ty) => {{
            let t = Instant::now();
            let r0 = rss_mb();
            let v: Option<$t> = f.decode_section($k).unwrap();
            println!(
                "{:?}: {:.2}s rss +{:.0} MB",
                $k,
                t.elapsed().as_secs_f64(),
                rss_mb() - r0
            );
            v
        }};
    }
    let b = one!(SectionKind::Buildings, Vec<citywalk_scenes::city::Building>);
    let o: Option<citywalk_scenes::occluder::OccluderSet> = if runtime {
        None
    } else {
        one!(
            SectionKind::Occluders,
            citywalk_scenes::occluder::OccluderSet
        )
    };
    let c = one!(
        SectionKind::ClusterTree,
        citywalk_scenes::cluster_tree::ClusterTree
    );
    let _q = one!(SectionKind::Quadtree, citywalk_scenes::quadtree::BQuadtree);
    let _bl = one!(SectionKind::Blocks, citywalk_scenes::blocks::UrbanBlocks);
    let t = Instant::now();
    drop((b, o, c));
    println!("drop {:.2}s", t.elapsed().as_secs_f64());
    let t = Instant::now();
    let pkg = if runtime {
        f.decode_runtime().unwrap()
    } else {
        f.decode().unwrap()
    };
    println!(
        "full decode (incl check_sections) {:.2}s rss {:.0}",
        t.elapsed().as_secs_f64(),
        rss_mb()
    );
    let t = Instant::now();
    pkg.check_sections().unwrap();
    println!("check_sections {:.2}s", t.elapsed().as_secs_f64());
}
