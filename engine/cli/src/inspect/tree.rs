//! `citywalk inspect tree SCENE --level K -o map.png [--gltf clusters.glb]`: draws one level
//! of the legibility cluster tree (Chang et al. 2008, Yang et al. 2011) top-down, like Chang's
//! Figure 11: each cluster's hull filled in its own colour, the buildings drawn in a darker
//! shade of their cluster's colour, streets as grey lines.
//!
//! For a scene package the tree drawn is the package's own; it is rebuilt (and the output says
//! so) only when the package has none or `--chang` / `--binary` ask for other parameters than
//! it was built with. Any other input is loaded, split into blocks and clustered on the fly.
//! The per-level table counts triangles and polygons (planar faces: a wall quad is one
//! polygon, a roof one, as Chang et al. §9 count them); `--gltf` writes the meshes of the
//! chosen level's cut (cluster meshes, and the buildings left as leaves) with flat normals.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use citywalk_preprocess::blocks::build_blocks;
use citywalk_preprocess::cluster::build_cluster_tree;
use citywalk_preprocess::occluders::gltf_out::{GlbOptions, meshes_to_glb};
use citywalk_preprocess::occluders::polygons::planar_face_count;
use citywalk_scenes::cluster_tree::{
    ClusterDistance, ClusterNode, ClusterParams, ClusterTree, HullMerge, HullSimplify,
};
use citywalk_scenes::extrude::building_mesh;
use citywalk_scenes::{City, TriangleMesh};
use image::{Rgb, RgbImage};

/// Arguments of this inspection.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A scene package (.cwk) or any input citywalk loads (OSM PBF, GeoJSON, CityJSON, glTF/GLB,
    /// OBJ).
    scene: PathBuf,
    #[command(flatten)]
    input: crate::input_args::InputArgs,
    /// Tree level to draw (0 = root); leaves shallower than it are drawn as they are.
    #[arg(long, default_value_t = 2)]
    level: u32,
    /// Output PNG.
    #[arg(short = 'o', long = "output", default_value = "tree.png")]
    output: PathBuf,
    /// Width of the longer image side (pixels, 64 to 16,384).
    #[arg(long, default_value_t = 1600, value_parser = clap::value_parser!(u32).range(64..=16_384))]
    size: u32,
    /// Use Chang et al.'s choices (size-weighted distance, four-case merging, smallest-area
    /// simplification) instead of Yang et al.'s (rebuilds a package's tree unless it was built
    /// with them).
    #[arg(long)]
    chang: bool,
    /// Keep the binary merge tree (no depth reduction; rebuilds a package's tree unless it was
    /// built so).
    #[arg(long)]
    binary: bool,
    /// Also write the meshes of the level's cut as GLB: one mesh per cluster and per building
    /// left as a leaf, flat normals.
    #[arg(long, value_name = "OUT.glb")]
    gltf: Option<PathBuf>,
}

/// The parameters `--chang` and `--binary` ask for, on top of `base`.
fn requested_params(args: &Args, base: &ClusterParams) -> ClusterParams {
    let mut params = base.clone();
    if args.chang {
        params.distance = ClusterDistance::ChangSizeWeighted;
        params.merge = HullMerge::ChangCases;
        params.simplify = HullSimplify::ChangSmallestArea;
    }
    if args.binary {
        params.depth_lambda = None;
    }
    params
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let load = args.input.load_options(std::slice::from_ref(&args.scene))?;
    let (city, block_of_building, block_count, stored) =
        match crate::scene_input::open_package(&args.scene)? {
            Some(package) => {
                let city = package.city();
                (
                    city,
                    package.blocks.block_of_building,
                    package.blocks.blocks.len(),
                    Some(package.cluster_tree),
                )
            }
            None => {
                let city = crate::scene_input::load_city(&args.scene, &load)?;
                let blocks = build_blocks(&city);
                (city, blocks.block_of_building, blocks.blocks.len(), None)
            }
        };
    let base = match &stored {
        Some(Some(tree)) => tree.params.clone(),
        _ => ClusterParams::default(),
    };
    let params = requested_params(&args, &base);
    let (tree, origin) = match stored {
        Some(Some(tree)) if tree.params == params => (tree, "the package's own tree".to_owned()),
        stored => {
            let why = match stored {
                Some(Some(_)) => {
                    "rebuilt: --chang / --binary ask for other parameters than the package's"
                }
                Some(None) => "rebuilt: the package has no cluster tree",
                None => "built: the input is not a scene package",
            };
            let start = Instant::now();
            let tree = build_cluster_tree(&city, &block_of_building, &params)
                .with_context(|| format!("cluster tree of {}", args.scene.display()))?;
            let seconds = start.elapsed().as_secs_f64();
            let origin = format!(
                "{why} ({:.3} s, {:.0} buildings/s)",
                seconds,
                city.buildings.len() as f64 / seconds.max(1e-9)
            );
            (tree, origin)
        }
    };
    if let Err(e) = tree.check_invariants(&city) {
        anyhow::bail!("cluster tree invariants violated: {e}");
    }
    let cut = tree.cut_at_level(args.level);
    let image = draw(&city, &tree, &cut, args.size);
    image
        .save(&args.output)
        .with_context(|| format!("cannot write {}", args.output.display()))?;
    println!("cluster tree: {origin}");
    println!(
        "{} buildings, {} blocks, {} nodes, depth {}, {} clusters at level {}, {} merge \
         fallbacks -> {}",
        city.buildings.len(),
        block_count,
        tree.nodes.len(),
        tree.max_depth(),
        cut.len(),
        args.level,
        tree.stats.merge_fallbacks,
        args.output.display()
    );
    print_merge_fallbacks(&tree);
    let building_meshes: Vec<TriangleMesh> = city.buildings.iter().map(building_mesh).collect();
    print_level_polygons(&tree, &building_meshes);
    if let Some(path) = &args.gltf {
        let meshes = cut_meshes(&tree, &cut, &building_meshes);
        let written = meshes.iter().filter(|(_, m)| !m.indices.is_empty()).count();
        let bytes = meshes_to_glb(
            meshes,
            GlbOptions {
                generator: "citywalk inspect tree",
                scene_name: "cluster tree cut",
                flat_normals: true,
            },
        )?;
        std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
        println!(
            "wrote {} meshes of level {} to {}",
            written,
            args.level,
            path.display()
        );
    }
    Ok(())
}

/// The meshes of a cut, in cut order: a cluster's own mesh, or the buildings of a leaf.
fn cut_meshes<'a>(
    tree: &'a ClusterTree,
    cut: &[u32],
    building_meshes: &'a [TriangleMesh],
) -> Vec<(String, &'a TriangleMesh)> {
    let mut out = Vec::new();
    for &n in cut {
        let node = &tree.nodes[n as usize];
        let buildings = &tree.building_order[node.buildings.0 as usize..node.buildings.1 as usize];
        if node.is_leaf() {
            for b in buildings {
                if let Some(mesh) = building_meshes.get(b.index()) {
                    out.push((format!("building {}", b.0), mesh));
                }
            }
        } else {
            out.push((
                format!("cluster {n} ({} buildings)", buildings.len()),
                &node.mesh,
            ));
        }
    }
    out
}

/// Merges whose first construction failed, by reason: rescued by Chang's full hull search,
/// or left as the convex hull.
fn print_merge_fallbacks(tree: &ClusterTree) {
    let mut by_reason: std::collections::BTreeMap<String, (usize, usize)> =
        std::collections::BTreeMap::new();
    for f in &tree.stats.merge_fallback_log {
        let e = by_reason.entry(format!("{:?}", f.reason)).or_default();
        if f.convex_hull {
            e.1 += 1;
        } else {
            e.0 += 1;
        }
    }
    for (reason, (carved, convex)) in &by_reason {
        println!(
            "merge fallback {reason}: {carved} carved by the full hull search, {convex} convex hulls"
        );
    }
}

/// Triangles and polygons (planar faces, [`planar_face_count`]) drawn when the whole city is
/// shown at each level of the tree, against the input (Chang et al. §9 report polygon counts
/// per level: 285,039 → 131,409 at ε = 100, τ = 2), and the errors of the level's cluster
/// meshes (what holds a cut at that level: README "LOD criteria").
fn print_level_polygons(tree: &ClusterTree, building_meshes: &[TriangleMesh]) {
    let building_counts: Vec<(usize, usize)> = building_meshes
        .iter()
        .map(|m| (m.triangle_count(), planar_face_count(m)))
        .collect();
    let input = building_counts
        .iter()
        .fold((0, 0), |a, c| (a.0 + c.0, a.1 + c.1));
    println!(
        "level  nodes  triangles  polygons  share of input ({} triangles, {} polygons)  \
         clusters' geometric error m (median / max)  colour error m (median / max)",
        input.0, input.1
    );
    for level in 0..=tree.max_depth() {
        let cut = tree.cut_at_level(level);
        let (triangles, polygons) = cut
            .iter()
            .map(|&n| {
                let node = &tree.nodes[n as usize];
                if node.is_leaf() {
                    let (start, end) = node.buildings;
                    tree.building_order[start as usize..end as usize]
                        .iter()
                        .filter_map(|b| building_counts.get(b.index()))
                        .fold((0, 0), |a, c| (a.0 + c.0, a.1 + c.1))
                } else {
                    (node.mesh.triangle_count(), planar_face_count(&node.mesh))
                }
            })
            .fold((0, 0), |a, c| (a.0 + c.0, a.1 + c.1));
        let share = |x: usize, of: usize| 100.0 * x as f64 / of.max(1) as f64;
        let clusters: Vec<_> = cut
            .iter()
            .map(|&n| &tree.nodes[n as usize])
            .filter(|node| !node.is_leaf())
            .collect();
        let spread = |error: fn(&ClusterNode) -> f32| {
            let mut errors: Vec<f32> = clusters.iter().map(|&node| error(node)).collect();
            errors.sort_by(f32::total_cmp);
            match (errors.get(errors.len() / 2), errors.last()) {
                (Some(median), Some(max)) => format!("{median:>7.1} / {max:>7.1}"),
                _ => format!("{:>17}", "–"),
            }
        };
        println!(
            "{level:>5}  {:>5}  {triangles:>9}  {polygons:>8}  {:>6.1} % / {:>5.1} %  {}  {}",
            cut.len(),
            share(triangles, input.0),
            share(polygons, input.1),
            spread(|node| node.geometric_error_m),
            spread(|node| node.colour_error_m),
        );
        if cut.iter().all(|&n| tree.nodes[n as usize].is_leaf()) {
            break;
        }
    }
}

/// World-to-pixel mapping (y up in the world, down in the image).
struct View {
    min: [f64; 2],
    scale: f64,
    height: u32,
}

impl View {
    fn px(&self, p: [f64; 2]) -> [f64; 2] {
        [
            (p[0] - self.min[0]) * self.scale,
            f64::from(self.height) - (p[1] - self.min[1]) * self.scale,
        ]
    }
}

/// A distinct colour per index (golden-ratio hue steps), light for hulls.
fn colour(i: usize, dark: bool) -> Rgb<u8> {
    let h = (i as f64 * 0.618_033_988_75).fract() * 6.0;
    let (s, v) = if dark { (0.75, 0.55) } else { (0.45, 0.95) };
    let c = v * s;
    let x = c * (1.0 - (h % 2.0 - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    let to = |f: f64| ((f + m) * 255.0).round().clamp(0.0, 255.0) as u8;
    Rgb([to(r), to(g), to(b)])
}

/// Even-odd scanline fill of polygons given as pixel-space rings.
fn fill(img: &mut RgbImage, rings: &[Vec<[f64; 2]>], c: Rgb<u8>) {
    let (w, h) = img.dimensions();
    let (mut ylo, mut yhi) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in rings.iter().flatten() {
        ylo = ylo.min(p[1]);
        yhi = yhi.max(p[1]);
    }
    if !ylo.is_finite() {
        return;
    }
    let y0 = ylo.floor().max(0.0) as u32;
    let y1 = (yhi.ceil().max(0.0) as u32).min(h);
    let mut xs = Vec::new();
    for y in y0..y1 {
        let yc = f64::from(y) + 0.5;
        xs.clear();
        for ring in rings {
            let n = ring.len();
            for i in 0..n {
                let (a, b) = (ring[i], ring[(i + 1) % n]);
                if (a[1] <= yc) != (b[1] <= yc) {
                    xs.push(a[0] + (yc - a[1]) / (b[1] - a[1]) * (b[0] - a[0]));
                }
            }
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks_exact(2) {
            let xa = (pair[0] - 0.5).ceil().max(0.0) as u32;
            let xb = ((pair[1] - 0.5).floor() + 1.0).clamp(0.0, f64::from(w)) as u32;
            for x in xa..xb {
                img.put_pixel(x, y, c);
            }
        }
    }
}

/// A one-pixel line (DDA).
fn line(img: &mut RgbImage, a: [f64; 2], b: [f64; 2], c: Rgb<u8>) {
    let (w, h) = img.dimensions();
    let steps = (b[0] - a[0])
        .abs()
        .max((b[1] - a[1]).abs())
        .ceil()
        .clamp(1.0, 100_000.0) as u32;
    for s in 0..=steps {
        let t = f64::from(s) / f64::from(steps);
        let (x, y) = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]));
        if x >= 0.0 && y >= 0.0 && (x as u32) < w && (y as u32) < h {
            img.put_pixel(x as u32, y as u32, c);
        }
    }
}

fn draw(city: &City, tree: &ClusterTree, cut: &[u32], size: u32) -> RgbImage {
    let root = &tree.nodes[tree.root as usize];
    let (lo, hi) = (root.bounds_min, root.bounds_max);
    let margin = 0.03
        * f64::from(hi[0] - lo[0])
            .max(f64::from(hi[1] - lo[1]))
            .max(1.0);
    let min = [f64::from(lo[0]) - margin, f64::from(lo[1]) - margin];
    let ext = [
        f64::from(hi[0] - lo[0]) + 2.0 * margin,
        f64::from(hi[1] - lo[1]) + 2.0 * margin,
    ];
    let scale = f64::from(size) / ext[0].max(ext[1]);
    let (w, h) = (
        ((ext[0] * scale).ceil() as u32).max(1),
        ((ext[1] * scale).ceil() as u32).max(1),
    );
    let view = View {
        min,
        scale,
        height: h,
    };
    let mut img = RgbImage::from_pixel(w, h, Rgb([255, 255, 255]));
    for (k, &n) in cut.iter().enumerate() {
        let node = &tree.nodes[n as usize];
        let rings: Vec<Vec<[f64; 2]>> = node
            .footprint
            .iter()
            .map(|r| {
                tree.ring_coords(r)
                    .into_iter()
                    .map(|p| view.px(p))
                    .collect()
            })
            .collect();
        fill(&mut img, &rings, colour(k, false));
    }
    for s in &city.streets {
        for seg in s.line.0.windows(2) {
            let (a, b) = (view.px([seg[0].x, seg[0].y]), view.px([seg[1].x, seg[1].y]));
            line(&mut img, a, b, Rgb([110, 110, 110]));
        }
    }
    for (k, &n) in cut.iter().enumerate() {
        let node = &tree.nodes[n as usize];
        let dark = colour(k, true);
        for b in &tree.building_order[node.buildings.0 as usize..node.buildings.1 as usize] {
            let Some(building) = city.buildings.get(b.index()) else {
                continue;
            };
            for poly in &building.footprint.0 {
                let rings: Vec<Vec<[f64; 2]>> = std::iter::once(poly.exterior())
                    .chain(poly.interiors())
                    .map(|r| r.0.iter().map(|c| view.px([c.x, c.y])).collect())
                    .collect();
                fill(&mut img, &rings, dark);
            }
        }
        for r in &node.footprint {
            let pts: Vec<[f64; 2]> = tree
                .ring_coords(r)
                .into_iter()
                .map(|p| view.px(p))
                .collect();
            for i in 0..pts.len() {
                line(
                    &mut img,
                    pts[i],
                    pts[(i + 1) % pts.len()],
                    Rgb([40, 40, 40]),
                );
            }
        }
    }
    img
}
