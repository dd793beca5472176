//! `citywalk inspect tree` end to end on a small package (a generated city preprocessed by the
//! binary): the package's own tree is drawn (the PNG decodes and is not blank), the per-level
//! table counts polygons beside triangles, `--gltf` writes one mesh per cluster and per
//! building left as a leaf of the cut, with flat unit normals; `--binary` and non-package
//! inputs say that the tree was rebuilt. CPU only.

use std::ffi::OsStr;
use std::path::Path;
use std::process::Command;

use citywalk_scenes::extrude::building_mesh;
use citywalk_scenes::package::ScenePackage;

#[path = "support/scratch.rs"]
mod scratch;
use scratch::temp_dir;

/// Runs the binary; panics with its output unless it succeeds; returns its stdout.
fn citywalk<S: AsRef<OsStr>>(args: &[S]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .args(args)
        .output()
        .expect("run citywalk");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "citywalk {:?} failed:\n{stdout}\n{}",
        args.iter().map(|a| a.as_ref()).collect::<Vec<_>>(),
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

#[test]
fn inspect_tree_draws_and_exports_the_packages_tree() {
    let dir = temp_dir("inspect-tree-package");
    let geojson = dir.join("city.geojson");
    let package = dir.join("city.cwk");
    citywalk(&[
        "generate",
        "--buildings",
        "150",
        "--seed",
        "5",
        "-o",
        path_str(&geojson),
    ]);
    citywalk(&[
        "preprocess",
        path_str(&geojson),
        "-o",
        path_str(&package),
        "--no-occluders",
    ]);
    let pkg = ScenePackage::read(&package).expect("package reads");
    let tree = pkg.cluster_tree.as_ref().expect("the package has a tree");
    // The shallowest level whose cut has several nodes, clusters among them.
    let level = (1..=tree.max_depth())
        .find(|&l| {
            let cut = tree.cut_at_level(l);
            cut.len() >= 3 && cut.iter().any(|&n| !tree.nodes[n as usize].is_leaf())
        })
        .expect("a level with several clusters");
    let cut = tree.cut_at_level(level);
    let clusters = cut
        .iter()
        .filter(|&&n| {
            let node = &tree.nodes[n as usize];
            !node.is_leaf() && !node.mesh.indices.is_empty()
        })
        .count();
    let leaf_buildings = cut
        .iter()
        .filter(|&&n| tree.nodes[n as usize].is_leaf())
        .map(|&n| {
            let b = tree.building_order[tree.nodes[n as usize].buildings.0 as usize];
            usize::from(!building_mesh(&pkg.buildings[b.index()]).indices.is_empty())
        })
        .sum::<usize>();
    assert!(clusters > 0);

    let png = dir.join("map.png");
    let glb = dir.join("cut.glb");
    let level_arg = level.to_string();
    let stdout = citywalk(&[
        "inspect",
        "tree",
        path_str(&package),
        "--level",
        &level_arg,
        "-o",
        path_str(&png),
        "--size",
        "300",
        "--gltf",
        path_str(&glb),
    ]);
    assert!(
        stdout.contains("cluster tree: the package's own tree"),
        "{stdout}"
    );
    assert!(
        stdout.contains(&format!(
            "{} nodes, depth {}",
            tree.nodes.len(),
            tree.max_depth()
        )),
        "{stdout}"
    );
    // Polygons (planar faces) beside triangles: fewer polygons than triangles.
    let header = stdout
        .lines()
        .find(|l| l.starts_with("level  nodes  triangles  polygons"))
        .unwrap_or_else(|| panic!("no level table:\n{stdout}"));
    let numbers: Vec<usize> = header
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|w| w.parse().ok())
        .collect();
    assert!(matches!(numbers[..], [t, p] if 0 < p && p < t), "{header}");
    // Level 0 is the root alone: its errors are the median and the maximum of its row.
    let root = &tree.nodes[0];
    let level_0 = stdout
        .lines()
        .find(|l| l.trim_start().starts_with("0 "))
        .unwrap_or_else(|| panic!("no level 0 row:\n{stdout}"));
    for error in [root.geometric_error_m, root.colour_error_m] {
        let shown = format!("{error:.1} / ");
        assert!(level_0.contains(&shown), "{shown} not in {level_0}");
    }

    let image = image::open(&png).expect("the PNG decodes").to_rgb8();
    assert_eq!(image.width().max(image.height()), 300);
    let first = *image.get_pixel(0, 0);
    assert!(image.pixels().any(|p| *p != first), "blank map");

    let bytes = std::fs::read(&glb).expect("GLB written");
    let gltf = gltf::Gltf::from_slice(&bytes).expect("the GLB loads");
    let blob = gltf.blob.as_deref().expect("binary chunk");
    let names: Vec<String> = gltf
        .meshes()
        .map(|m| m.name().unwrap_or_default().to_owned())
        .collect();
    assert_eq!(names.len(), clusters + leaf_buildings, "{names:?}");
    assert_eq!(
        names.iter().filter(|n| n.starts_with("cluster ")).count(),
        clusters
    );
    assert!(stdout.contains(&format!("wrote {} meshes", names.len())));
    for mesh in gltf.meshes() {
        for prim in mesh.primitives() {
            let reader = prim.reader(|_| Some(blob));
            let pos: Vec<[f32; 3]> = reader.read_positions().expect("positions").collect();
            let nor: Vec<[f32; 3]> = reader
                .read_normals()
                .unwrap_or_else(|| panic!("{:?} has no normals", mesh.name()))
                .collect();
            assert_eq!(nor.len(), pos.len());
            assert!(!pos.is_empty() && pos.len().is_multiple_of(3));
            let v = |a: [f32; 3]| glam::Vec3::from_array(a);
            for (t, n) in pos.chunks_exact(3).zip(nor.chunks_exact(3)) {
                // Flat: one unit normal per triangle, on the side its winding faces.
                assert!(n[0] == n[1] && n[1] == n[2]);
                assert!((v(n[0]).length() - 1.0).abs() < 1e-5);
                let g = (v(t[1]) - v(t[0])).cross(v(t[2]) - v(t[0]));
                assert!(g.length() == 0.0 || g.normalize().dot(v(n[0])) > 0.999);
            }
        }
    }

    // Other parameters than the package's rebuild the tree, and say so.
    let stdout = citywalk(&[
        "inspect",
        "tree",
        path_str(&package),
        "--binary",
        "-o",
        path_str(&png),
        "--size",
        "128",
    ]);
    assert!(
        stdout.contains("cluster tree: rebuilt: --chang / --binary"),
        "{stdout}"
    );
    // Any other input is clustered on the fly.
    let stdout = citywalk(&[
        "inspect",
        "tree",
        path_str(&geojson),
        "-o",
        path_str(&png),
        "--size",
        "128",
    ]);
    assert!(
        stdout.contains("cluster tree: built: the input is not a scene package"),
        "{stdout}"
    );
    std::fs::remove_dir_all(&dir).expect("clean up");
}
