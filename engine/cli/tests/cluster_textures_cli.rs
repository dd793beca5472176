//! `preprocess --cluster-textures` and `inspect textures` end to end: the binary bakes the
//! cluster textures on a headless GPU into the package, says what it baked, and writes them
//! back out as one PNG per page and view; without a cluster tree, or from a package without
//! textures, it says why it cannot.

#[path = "support/gpu.rs"]
mod gpu;
#[path = "support/run_cli.rs"]
mod run_cli;
#[path = "support/scratch.rs"]
mod scratch;

use citywalk_scenes::cluster_texture::atlas::AtlasView;
use citywalk_scenes::package::ScenePackage;
use run_cli::{citywalk, path_str, text};
use scratch::temp_dir;

#[test]
fn preprocess_bakes_the_cluster_textures_and_inspect_writes_them_out() {
    if !gpu::gpu_available("preprocess_bakes_the_cluster_textures_and_inspect_writes_them_out") {
        return;
    }
    let dir = temp_dir("cluster-textures-cli");
    let geojson = dir.join("city.geojson");
    let package = dir.join("city.cwk");
    let out = citywalk(&[
        "generate",
        "--buildings",
        "150",
        "--seed",
        "11",
        "-o",
        path_str(&geojson),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    let out = citywalk(&[
        "preprocess",
        path_str(&geojson),
        "-o",
        path_str(&package),
        "--cluster-textures",
        "--texture-bin-px",
        "128",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON summary");
    let baked = &summary["cluster_textures"];
    let clusters = baked["clusters"].as_u64().expect("textured clusters");
    assert!(clusters > 0, "{baked}");
    assert!(baked["compressed_bytes"].as_u64().unwrap() > 0);

    let pkg = ScenePackage::read(&package).expect("the package reads");
    let tree = pkg.cluster_tree.as_ref().expect("a tree");
    let textures = pkg
        .cluster_textures
        .as_ref()
        .expect("the package has textures");
    textures.check(tree).expect("textures match the tree");
    assert_eq!(textures.layout.clusters.len() as u64, clusters);
    assert_eq!(textures.layout.page_px, 128);
    let inner = tree.nodes.iter().filter(|n| !n.is_leaf()).count() as u64;
    assert_eq!(
        baked["candidates"].as_u64(),
        Some(inner),
        "every cluster mesh"
    );

    let pngs = dir.join("textures");
    let out = citywalk(&[
        "inspect",
        "textures",
        path_str(&package),
        "-o",
        path_str(&pngs),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains(&format!("{clusters} textured clusters")),
        "{}",
        text(&out)
    );
    assert!(textures.layout.page_count as usize >= textures.layout.bins.len());
    for page in 0..textures.layout.page_count {
        for view in AtlasView::ALL {
            let path = pngs.join(format!("page{page:03}_{}.png", view.name()));
            let image = image::open(&path).expect("a PNG per page and view");
            assert_eq!(
                (image.width(), image.height()),
                (128, 128),
                "{}",
                path.display()
            );
        }
    }
    let out = citywalk(&["inspect", path_str(&package), "--check"]);
    assert!(out.status.success(), "{}", text(&out));
    assert!(
        text(&out).contains("section cluster textures")
            && text(&out).contains(&format!("cluster textures: {clusters} clusters in"))
            && text(&out).contains("check: all invariants hold"),
        "{}",
        text(&out)
    );
}

#[test]
fn textures_need_a_tree_and_a_package_that_has_them() {
    let dir = temp_dir("cluster-textures-cli-errors");
    let geojson = dir.join("city.geojson");
    let package = dir.join("city.cwk");
    let out = citywalk(&[
        "generate",
        "--buildings",
        "20",
        "--seed",
        "3",
        "-o",
        path_str(&geojson),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    // Refused before any GPU is needed.
    let out = citywalk(&[
        "preprocess",
        path_str(&geojson),
        "-o",
        path_str(&package),
        "--cluster-textures",
        "--no-cluster-tree",
    ]);
    assert!(!out.status.success());
    assert!(
        text(&out).contains("--cluster-textures needs the cluster tree"),
        "{}",
        text(&out)
    );
    assert!(!package.exists(), "nothing written");
    let out = citywalk(&["preprocess", path_str(&geojson), "-o", path_str(&package)]);
    assert!(out.status.success(), "{}", text(&out));
    let out = citywalk(&[
        "inspect",
        "textures",
        path_str(&package),
        "-o",
        path_str(&dir.join("none")),
    ]);
    assert!(!out.status.success());
    assert!(
        text(&out).contains("has no cluster textures (preprocess it with --cluster-textures)"),
        "{}",
        text(&out)
    );
    assert!(!text(&out).contains("panicked"), "{}", text(&out));
}
