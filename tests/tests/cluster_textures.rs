//! The cluster texture bake (Chang et al. 2008 §7) on a GPU: each wall of a cluster mesh shows
//! the facades of the buildings behind it, at the cluster's height, and the roof views show
//! their roofs; the textures survive the package.

use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_runtime::render::debug::clusters::hash_u32;
use citywalk_runtime::texture_bake::{bake_cluster_textures, cluster_walls};
use citywalk_scenes::cluster_texture::atlas::AtlasView;
use citywalk_scenes::cluster_texture::atlas::layout_atlas;
use citywalk_scenes::cluster_texture::baked::{ClusterTextures, compress_page};
use citywalk_scenes::cluster_texture::roof_views::RoofView;
use citywalk_scenes::cluster_texture::side_layout::BORDER_PX;
use citywalk_scenes::package::{ScenePackage, WriteOptions};
use citywalk_shaders::constants::BARE_GROUND_SRGB;
use citywalk_tests::city_builder::boxes;
use citywalk_tests::gpu::{diff_rgba, gpu_or_skip};

/// The sRGB bytes an sRGB target stores for a linear value.
fn srgb_byte(linear: f32) -> u8 {
    let l = linear.clamp(0.0, 1.0);
    let s = if l <= 0.003_130_8 {
        12.92 * l
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// CPU twin of `facade_colour` in `wgsl/shared/materials.wgsl`, as the baked texture stores it.
fn facade_srgb(id: u32) -> [u8; 3] {
    let h = hash_u32(id);
    let palette = [
        [0.80, 0.72, 0.58],
        [0.64, 0.36, 0.27],
        [0.90, 0.88, 0.82],
        [0.60, 0.61, 0.62],
        [0.78, 0.66, 0.48],
        [0.47, 0.56, 0.66],
    ];
    let base: [f32; 3] = palette[(h % 6) as usize];
    let jitter = ((h >> 8) & 255) as f32 / 255.0;
    base.map(|c| srgb_byte((c * (0.88 + 0.2 * jitter)).powf(2.2)))
}

/// CPU twin of `roof_colour` in `wgsl/shared/materials.wgsl`, as the baked texture stores it.
fn roof_srgb(id: u32) -> [u8; 3] {
    let h = hash_u32(id ^ 0x9e37_79b9);
    let shade = 0.40 + 0.16 * (h & 255) as f32 / 255.0;
    [shade * 1.02, shade, shade * 0.98].map(|c| srgb_byte(c.powf(2.2)))
}

fn close(a: &[u8], b: [u8; 3]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= 2)
}

#[test]
fn walls_show_the_facades_behind_them_and_roofs_their_roofs() {
    let Some(gpu) = gpu_or_skip("walls_show_the_facades_behind_them_and_roofs_their_roofs") else {
        return;
    };
    // A terrace of three houses sharing walls, 8, 14 and 10 m tall: one cluster, a 30 × 10 m
    // box, whose south wall stands on the three houses' fronts.
    let city = boxes(&[
        (0.0, 0.0, 10.0, 10.0, 8.0),
        (10.0, 0.0, 20.0, 10.0, 14.0),
        (20.0, 0.0, 30.0, 10.0, 10.0),
    ]);
    let mut package =
        preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let tree = package.cluster_tree.as_ref().expect("a cluster tree");
    let root = tree.root;
    assert!(!tree.nodes[root as usize].is_leaf());
    let walls = cluster_walls(tree);
    let root_walls = walls
        .iter()
        .find(|w| w.node == root)
        .expect("the root's walls");
    let (textures, stats) =
        bake_cluster_textures(&gpu, &package.gpu_scene.view(), tree, 64).expect("bake");
    assert_eq!(stats.clusters, stats.candidates);
    textures.check(tree).expect("textures match the tree");
    let placement = textures
        .layout
        .placement(root)
        .expect("the root is textured");
    let bin = textures.layout.bins[placement.bin as usize];
    let page = placement.page as usize;
    let page_px = textures.layout.page_px;
    let side = textures.decode(page, AtlasView::Side).unwrap();
    let texel = |x: u32, y: u32| {
        let at = ((y * side.width + x) * 4) as usize;
        side.rgba[at..at + 3].to_vec()
    };

    // The south wall: the ring edge along y = 0, running east.
    let n = root_walls.ring.len();
    let south = (0..n)
        .find(|&i| {
            let (a, b) = (root_walls.ring[i], root_walls.ring[(i + 1) % n]);
            a[1].abs() < 1e-3 && b[1].abs() < 1e-3 && b[0] > a[0]
        })
        .expect("a south wall");
    let (a, b) = (root_walls.ring[south], root_walls.ring[(south + 1) % n]);
    let rect = placement.face_rect_px(&bin, south).unwrap();
    for x in 0..rect.width_px {
        // The metre of the wall at this texel's centre: which house stands there.
        let along = (x as f32 + 0.5) / rect.width_px as f32;
        let metre = a[0] + (b[0] - a[0]) * along;
        if (metre - 10.0).abs() < 1.0 || (metre - 20.0).abs() < 1.0 {
            continue;
        }
        let house = (metre / 10.0).floor() as u32;
        // Every house scaled to the cluster's height: its facade fills the wall's height.
        for y in 0..rect.height_px {
            let got = texel(rect.x_px + x, rect.y_px + y);
            assert!(
                close(&got, facade_srgb(house)),
                "wall texel ({x}, {y}) at {metre} m: {got:?}, house {house} is {:?}",
                facade_srgb(house)
            );
        }
    }
    // The border repeats the rectangle's edge.
    let b = BORDER_PX;
    assert_eq!(
        texel(rect.x_px - b, rect.y_px + 3),
        texel(rect.x_px, rect.y_px + 3)
    );
    assert_eq!(
        texel(rect.x_px + 3, rect.y_px + rect.height_px - 1 + b),
        texel(rect.x_px + 3, rect.y_px + rect.height_px - 1)
    );

    // The top view: over each house, that house's roof (north up, east right: a flipped or
    // mirrored image would put another house there).
    let top = textures
        .decode(page, AtlasView::Roof(RoofView::Top))
        .unwrap();
    let roof_at = |x_m: f32, y_m: f32| {
        let point = glam::Vec3::new(x_m, y_m, placement.box_hi_m[2]);
        let [u, v] = placement.roof_uv(&bin, page_px, RoofView::Top, point);
        let (x, y) = (
            (u * top.width as f32) as u32,
            (v * top.height as f32) as u32,
        );
        let at = ((y * top.width + x) * 4) as usize;
        top.rgba[at..at + 3].to_vec()
    };
    for (x_m, y_m, house) in [(5.0, 5.0, 0), (15.0, 3.0, 1), (25.0, 7.0, 2)] {
        let got = roof_at(x_m, y_m);
        assert!(
            close(&got, roof_srgb(house)),
            "roof at ({x_m}, {y_m}): {got:?}, house {house}'s is {:?}",
            roof_srgb(house)
        );
    }
    let middle = glam::Vec3::new(15.0, 5.0, placement.box_hi_m[2]);
    // From the south, 45° down, the middle of the box's image is the middle house's front or
    // roof: a building, not ground.
    let south_view = textures
        .decode(page, AtlasView::Roof(RoofView::South))
        .unwrap();
    let [u, v] = placement.roof_uv(&bin, page_px, RoofView::South, middle);
    let (x, y) = (
        (u * top.width as f32) as u32,
        (v * top.height as f32) as u32,
    );
    let at = ((y * south_view.width + x) * 4) as usize;
    let seen = &south_view.rgba[at..at + 3];
    let ground = [
        srgb_byte(BARE_GROUND_SRGB[0].powf(2.2)),
        srgb_byte(BARE_GROUND_SRGB[2].powf(2.2)),
    ];
    assert!(
        !(seen[0].abs_diff(ground[0]) <= 2 && seen[2].abs_diff(ground[1]) <= 2),
        "south view sees ground {seen:?}"
    );

    // The textures go into the package and come back the same.
    package.cluster_textures = Some(textures.clone());
    let bytes = package.to_bytes(WriteOptions::default()).unwrap();
    let back = ScenePackage::from_bytes(&bytes).unwrap();
    assert_eq!(back.cluster_textures.as_ref(), Some(&textures));
    assert!(back.check_invariants().is_ok());
}

/// Textures of `package`'s tree laid out on pages of 32 texels, each page a blank PNG: what
/// `check` reads, without a GPU.
fn blank_textures(package: &ScenePackage) -> ClusterTextures {
    let tree = package.cluster_tree.as_ref().unwrap();
    let layout = layout_atlas(&cluster_walls(tree), 32);
    let blank = vec![vec![0u8; 32 * 32 * 4]; 6];
    let images = (0..layout.page_count as usize)
        .map(|page| compress_page(32, page, &blank).unwrap())
        .collect();
    ClusterTextures::from_compressed(layout, images).unwrap()
}

#[test]
fn damaged_texture_layouts_are_refused_with_their_reason() {
    let city = boxes(&[
        (0.0, 0.0, 10.0, 10.0, 8.0),
        (10.0, 0.0, 20.0, 10.0, 14.0),
        (40.0, 0.0, 50.0, 12.0, 10.0),
        (40.0, 14.0, 50.0, 24.0, 12.0),
    ]);
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let tree = package.cluster_tree.as_ref().unwrap();
    let good = blank_textures(&package);
    assert!(
        good.layout.clusters.len() >= 2,
        "{:?}",
        good.layout.clusters.len()
    );
    good.check(tree).expect("a sound layout passes");
    let refused = |damage: &dyn Fn(&mut ClusterTextures), reason: &str| {
        let mut t = good.clone();
        damage(&mut t);
        let err = t.check(tree).expect_err(reason);
        assert!(err.contains(reason), "{reason}: {err}");
    };
    refused(
        &|t| t.layout.clusters[0].sides.faces[0].x_px = u32::MAX - 1,
        "wall 0's rectangle lies outside its cell",
    );
    refused(
        &|t| t.layout.clusters[0].box_hi_m[2] = f32::NAN,
        "its box is not finite and ordered",
    );
    refused(
        &|t| {
            let first = t.layout.clusters[0].clone();
            let second = &mut t.layout.clusters[1];
            (second.bin, second.page, second.cell) = (first.bin, first.page, first.cell);
            second.sides = first.sides;
        },
        "cell",
    );
    refused(&|t| t.layout.page_px = 0, "pages of 0 texels");
    refused(&|t| t.layout.page_px = 1 << 20, "not 1 to 8192");
    refused(&|t| t.layout.bins[0].page_count += 1, "pages");
    refused(
        &|t| t.images.truncate(t.images.len() - 1),
        "pages of textures",
    );
    refused(
        &|t| t.images[0][3] = b"not a png".to_vec(),
        "page 0, east view",
    );
    refused(
        &|t| t.layout.clusters[0].node = tree.building_order.len() as u32 * 10,
        "which the tree lacks",
    );
}

/// Mean absolute difference per channel (RGB) of two images of one size.
fn mean_abs_diff(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    let sum: u64 = a
        .pixels()
        .zip(b.pixels())
        .map(|(p, q)| {
            (0..3)
                .map(|c| u64::from(p.0[c].abs_diff(q.0[c])))
                .sum::<u64>()
        })
        .sum();
    sum as f64 / (3 * a.width() * a.height()) as f64
}

/// Chang et al. 2008 §9 in small: drawn far enough that the LOD cut takes cluster meshes, a
/// city whose clusters carry their baked textures looks more like the full city than one whose
/// clusters are flat-coloured, in the LOD frame of the CPU cut and in the occlusion-culled one.
#[test]
fn textured_clusters_look_more_like_the_full_city_than_flat_ones() {
    use citywalk_runtime::camera::Camera;
    use citywalk_runtime::cluster_textures::ClusterShading;
    use citywalk_runtime::drawable::DrawableScene;
    use citywalk_runtime::frame::Visibility;
    use citywalk_runtime::lod::LodCriterion;
    use citywalk_runtime::plan::FramePlan;
    use citywalk_runtime::render::{BruteRenderer, OffscreenTarget};
    use citywalk_runtime::runner::{Completion, FrameRunner, FrameTarget};
    use citywalk_scenes::generate::{GenerateParams, generate_city};
    use glam::Vec3;

    let Some(gpu) = gpu_or_skip("textured_clusters_look_more_like_the_full_city_than_flat_ones")
    else {
        return;
    };
    let city = generate_city(&GenerateParams::new(600, 11)).expect("generate");
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let tree = package.cluster_tree.clone().expect("a cluster tree");
    let (textures, _) =
        bake_cluster_textures(&gpu, &package.gpu_scene.view(), &tree, 512).expect("bake");
    let mut scene =
        DrawableScene::upload_package(&gpu, &package.gpu_scene, Some(tree), None).expect("upload");
    scene
        .add_cluster_textures(&gpu, &package.gpu_scene, textures, 64)
        .expect("textures within the budget");
    let texturing = scene.texturing().expect("the LOD scene is textured");
    assert!(
        texturing.summary.rejected.is_empty(),
        "{:?}",
        texturing.summary.rejected
    );
    assert!(texturing.summary.textured_clusters > 10);

    let (lo, hi) = scene.buildings.bounds;
    let centre = (lo + hi) * 0.5;
    // Looking north-east and down at the city from its south-west, a few hundred metres out.
    let camera = Camera::new(
        Vec3::new(lo.x - 150.0, lo.y - 150.0, 260.0),
        45f32.to_radians(),
        -35f32.to_radians(),
    );
    assert!(camera.forward().dot(centre - camera.position) > 0.0);
    let (width, height) = (480, 270);
    let format = BruteRenderer::PNG_FORMAT;
    let target = OffscreenTarget::new(&gpu, width, height, format).expect("target");
    let read = |target: &OffscreenTarget| {
        image::RgbaImage::from_raw(width, height, target.read_colour(&gpu).expect("read"))
            .expect("size")
    };
    let full = {
        let renderer = BruteRenderer::new(&gpu, format);
        let rgba = renderer
            .render_rgba(&gpu, &scene.buildings, &camera, width, height)
            .expect("brute frame");
        image::RgbaImage::from_raw(width, height, rgba).expect("size")
    };
    // A coarse cut: clusters stand for most of the city.
    let criterion = Some(LodCriterion::Geometric { tolerance_px: 24.0 });
    let lod_only = FramePlan {
        lod: true,
        ..FramePlan::NONE
    };
    for plan in [lod_only, FramePlan::ALL] {
        let mut runner = FrameRunner::new(&gpu, format);
        let mut visibility = Visibility::default();
        let mut frame = |textured: bool| {
            texturing.set_shading(if textured {
                ClusterShading::Textured
            } else {
                ClusterShading::Flat
            });
            let report = runner
                .run(
                    &gpu,
                    scene.refs(),
                    plan,
                    criterion,
                    &mut visibility,
                    &camera,
                    FrameTarget::offscreen(&target),
                    (Completion::Wait, false),
                )
                .expect("frame")
                .expect("a waited frame's report");
            (read(&target), report)
        };
        let (flat, report) = frame(false);
        let clusters = report.clusters_drawn.unwrap_or(0);
        assert!(
            clusters > 10,
            "{}: {clusters} clusters drawn",
            plan.describe()
        );
        // The first textured frame asks for its pages; they are resident for the next.
        frame(true);
        texturing.settle(&gpu);
        let (textured, _) = frame(true);
        let residency = texturing.residency();
        assert!(residency.broken.is_empty(), "{:?}", residency.broken);
        let resident = residency.resident;
        assert!(resident > 0 && residency.uploaded >= resident as u64);
        assert!(resident <= residency.layers && residency.resident_mib <= 64.0);
        let (flat_error, textured_error) =
            (mean_abs_diff(&flat, &full), mean_abs_diff(&textured, &full));
        let changed = diff_rgba(&flat, &textured, 8).differing;
        eprintln!(
            "{}: {clusters} clusters, {resident} page views resident; mean error against the full city: flat {flat_error:.2}, textured {textured_error:.2}; {changed} pixels changed",
            plan.describe()
        );
        if let Ok(dir) = std::env::var("CITYWALK_TEXTURE_IMAGES") {
            for (name, image) in [("full", &full), ("flat", &flat), ("textured", &textured)] {
                let _ = image.save(format!(
                    "{dir}/{}_{name}.png",
                    plan.lod as u8 + plan.hzb as u8
                ));
            }
        }
        assert!(changed > 500, "the textures show: {changed} pixels changed");
        assert!(
            textured_error < 0.9 * flat_error,
            "textured {textured_error:.2} against flat {flat_error:.2}"
        );
    }
}

/// Golden image of one textured cluster: the terrace of three houses (8, 14 and 10 m) drawn as
/// its one cluster mesh, a 30 × 10 m box 11 m tall (its roof height, midway between 8 and
/// 14 m), from the south-west and above, so that the south and west walls and the roof show
/// their baked images (the three facades on the south wall, the roofs' greys in the roof view
/// from the south). Tolerance: per-channel difference ≤ 8 on ≥ 99 % of pixels; the golden was
/// set on lavapipe (llvmpipe, Mesa 22.3.6, Vulkan). Regenerate with `CITYWALK_UPDATE_GOLDEN=1`.
#[test]
fn one_textured_cluster_matches_golden() {
    use citywalk_runtime::camera::Camera;
    use citywalk_runtime::drawable::DrawableScene;
    use citywalk_runtime::frame::Visibility;
    use citywalk_runtime::lod::LodCriterion;
    use citywalk_runtime::plan::FramePlan;
    use citywalk_runtime::render::{BruteRenderer, OffscreenTarget};
    use citywalk_runtime::runner::{Completion, FrameRunner, FrameTarget};
    use citywalk_tests::gpu::assert_matches_golden;
    use glam::Vec3;

    let Some(gpu) = gpu_or_skip("one_textured_cluster_matches_golden") else {
        return;
    };
    let city = boxes(&[
        (0.0, 0.0, 10.0, 10.0, 8.0),
        (10.0, 0.0, 20.0, 10.0, 14.0),
        (20.0, 0.0, 30.0, 10.0, 10.0),
    ]);
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let tree = package.cluster_tree.clone().expect("a cluster tree");
    let (textures, _) =
        bake_cluster_textures(&gpu, &package.gpu_scene.view(), &tree, 64).expect("bake");
    let mut scene =
        DrawableScene::upload_package(&gpu, &package.gpu_scene, Some(tree), None).expect("upload");
    scene
        .add_cluster_textures(&gpu, &package.gpu_scene, textures, 16)
        .expect("textures within the budget");
    let texturing = scene.texturing().expect("textured");
    assert_eq!(texturing.summary.textured_clusters, 1);
    // From the south-west, 25 m out and 17 m up: the roof view is the south one.
    let camera = Camera::new(
        Vec3::new(-4.0, -24.0, 17.0),
        50f32.to_radians(),
        -26f32.to_radians(),
    );
    let (width, height) = (161, 97);
    let format = BruteRenderer::PNG_FORMAT;
    let target = OffscreenTarget::new(&gpu, width, height, format).expect("target");
    let mut runner = FrameRunner::new(&gpu, format);
    let mut visibility = Visibility::default();
    // A tolerance no cluster exceeds: the cut is the root, the one cluster.
    let criterion = Some(LodCriterion::Geometric {
        tolerance_px: 1.0e6,
    });
    let plan = FramePlan {
        lod: true,
        ..FramePlan::NONE
    };
    let mut frame = || {
        runner
            .run(
                &gpu,
                scene.refs(),
                plan,
                criterion,
                &mut visibility,
                &camera,
                FrameTarget::offscreen(&target),
                (Completion::Wait, false),
            )
            .expect("frame")
            .expect("a waited frame's report")
    };
    let report = frame();
    assert_eq!(report.clusters_drawn, Some(1), "{:?}", report.ids);
    texturing.settle(&gpu);
    frame();
    assert_eq!(
        texturing.residency().resident,
        2,
        "the side view and the south roof view"
    );
    let image =
        image::RgbaImage::from_raw(width, height, target.read_colour(&gpu).expect("read back"))
            .expect("size");
    assert_matches_golden("textured_cluster_161x97.png", &image, 8, 0.99);
}

/// The shader's texel mappings (`wall_texel`, `roof_texel` in
/// `shaders/wgsl/shared/cluster_textures.wgsl`), run on the GPU through the tables a load
/// builds, against their CPU reference: the layout's `SideLayout::uv` for a wall point and
/// `ClusterPlacement::roof_uv` for a roof point seen by each of the five roof views, on the
/// image axes the runtime gives the shader (`roof_image_axes`).
#[test]
fn the_shader_maps_walls_and_roofs_to_the_texels_of_the_layout() {
    use citywalk_runtime::cluster_textures::{MeshArrays, TextureTables, roof_image_axes};
    use glam::Vec3;
    use wgpu::util::DeviceExt;

    let Some(gpu) = gpu_or_skip("the_shader_maps_walls_and_roofs_to_the_texels_of_the_layout")
    else {
        return;
    };
    let city = boxes(&[
        (0.0, 0.0, 10.0, 10.0, 8.0),
        (10.0, 0.0, 20.0, 10.0, 14.0),
        (20.0, 2.0, 31.0, 9.0, 11.0),
        (40.0, 0.0, 50.0, 12.0, 10.0),
        (40.0, 14.0, 50.0, 24.0, 12.0),
        (52.0, 16.0, 60.0, 30.0, 25.0),
    ]);
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let tree = package.cluster_tree.as_ref().unwrap();
    let layout = layout_atlas(&cluster_walls(tree), 1024);
    let scene = package.gpu_scene.view();
    let tables = TextureTables::build(
        &layout,
        MeshArrays {
            building_count: scene.building_count,
            node_count: tree.nodes.len() as u32,
            records: scene.records,
            vertices: scene.vertices,
            indices: scene.indices,
        },
    );
    assert!(tables.rejected.is_empty(), "{:?}", tables.rejected);
    assert!(tables.textured() >= 2, "{} textured", tables.textured());

    // Probes: (point, roof view or None for wall `wall`, cluster node, wall), and the texel
    // the layout gives each.
    let page = layout.page_px as f32;
    let mut probes: Vec<(Vec3, Option<RoofView>, u32, u32)> = Vec::new();
    let mut want: Vec<[f32; 2]> = Vec::new();
    for placement in &layout.clusters {
        let c = &tables.clusters[placement.node as usize];
        let bin = &layout.bins[placement.bin as usize];
        let [ox, oy] = bin.cell_origin_px(placement.cell).map(|v| v as f32);
        let side = placement.sides.side_px as f32;
        let record = &scene.records[(scene.building_count + placement.node) as usize];
        let vertex =
            |k: usize| Vec3::from(scene.vertices[record.base_vertex as usize + k].position_m);
        let n = c.wall_count as usize;
        for wall in 0..n {
            let (a, b) = (vertex(2 * wall), vertex(2 * ((wall + 1) % n)));
            for (along, up) in [(0.0, 0.0), (1.0, 1.0), (0.25, 0.6), (0.8, 0.1)] {
                let z = c.box_lo_m[2] + up * (c.box_hi_m[2] - c.box_lo_m[2]);
                probes.push((
                    a.lerp(b, along).with_z(z),
                    None,
                    placement.node,
                    wall as u32,
                ));
                let [u, v] = placement.sides.uv(wall, along, up);
                want.push([ox + u * side, oy + v * side]);
            }
        }
        let (lo, hi) = (
            Vec3::from(placement.box_lo_m),
            Vec3::from(placement.box_hi_m),
        );
        for view in RoofView::ALL {
            for t in [
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(0.3, 0.7, 1.0),
                Vec3::new(0.9, 0.2, 0.5),
                Vec3::new(0.5, 0.5, 0.0),
            ] {
                let point = lo + (hi - lo) * t;
                probes.push((point, Some(view), placement.node, 0));
                let [u, v] = placement.roof_uv(bin, layout.page_px, view, point);
                want.push([u * page, v * page]);
            }
        }
    }

    // One 64-byte probe: point, right, down (vec4 each), then cluster, wall, roof flag.
    let mut words: Vec<u32> = Vec::new();
    for &(point, view, node, wall) in &probes {
        let [right, down] = view.map_or([Vec3::ZERO; 2], roof_image_axes);
        for v in [point, right, down] {
            words.extend(v.extend(0.0).to_array().map(f32::to_bits));
        }
        words.extend([node, wall, u32::from(view.is_some()), 0]);
    }
    let source = format!(
        "{}{}",
        citywalk_shaders::SHARED_WGSL,
        r#"
struct TexelProbe { point: vec4<f32>, right: vec4<f32>, down: vec4<f32>, cluster: u32, wall: u32, roof: u32, pad: u32 }
@group(0) @binding(0) var<storage, read> clusters: array<TexturedCluster>;
@group(0) @binding(1) var<storage, read> walls: array<TexturedWall>;
@group(0) @binding(2) var<storage, read> probes: array<TexelProbe>;
@group(0) @binding(3) var<storage, read_write> texels: array<vec2<f32>>;
@compute @workgroup_size(64)
fn probe_texels(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= arrayLength(&probes) { return; }
    let p = probes[id.x];
    let cluster = clusters[p.cluster];
    if p.roof == 1u {
        texels[id.x] = roof_texel(cluster, p.right.xyz, p.down.xyz, p.point.xyz);
    } else {
        texels[id.x] = wall_texel(cluster, walls[cluster.first_wall + p.wall], p.point.xyz);
    }
}
"#
    );
    let device = &gpu.device;
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("texel probes"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("texel probes"),
        layout: None,
        module: &module,
        entry_point: Some("probe_texels"),
        compilation_options: Default::default(),
        cache: None,
    });
    let storage = |label: &str, contents: &[u8]| {
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage: wgpu::BufferUsages::STORAGE,
        })
    };
    let clusters = storage("clusters", bytemuck::cast_slice(&tables.clusters));
    let walls = storage("walls", bytemuck::cast_slice(&tables.walls));
    let probe_buffer = storage("probes", bytemuck::cast_slice(&words));
    let size = (probes.len() * 8) as u64;
    let texels = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("texels"),
        size,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let readback = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("texels readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("texel probes"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[&clusters, &walls, &probe_buffer, &texels]
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: b.as_entire_binding(),
            })
            .collect::<Vec<_>>(),
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups((probes.len() as u32).div_ceil(64), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&texels, 0, &readback, 0, size);
    gpu.queue.submit([encoder.finish()]);
    let bytes = citywalk_runtime::render::targets::map_read_prefix(&gpu, &readback, size)
        .expect("texels read back");
    let got: &[[f32; 2]] = bytemuck::cast_slice(&bytes);

    for (i, ((point, view, node, wall), want)) in probes.iter().zip(&want).enumerate() {
        let g = got[i];
        assert!(
            (g[0] - want[0]).abs() < 0.01 && (g[1] - want[1]).abs() < 0.01,
            "probe {i}: node {node}, {} at {point}: shader {g:?}, layout {want:?}",
            view.map_or(format!("wall {wall}"), |v| format!("roof view {v:?}"))
        );
    }
    // The walls and every roof view were probed.
    assert!(probes.iter().any(|p| p.1.is_none()));
    assert!(
        RoofView::ALL
            .iter()
            .all(|v| probes.iter().any(|p| p.1 == Some(*v)))
    );
}
