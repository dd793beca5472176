//! Cross-check of the GPU visibility oracle with CPU ray casting (obvhs): through a sample of
//! pixel centres, the first triangle hit must belong to the building the id image shows there,
//! except at pixels on an id edge (where rasterisation and ray casting may round differently).
//! Coplanar faces (a building mapped twice) are settled by the engine's depth tie rule on both
//! sides ([`depth_tie_factor`]).

use citywalk_runtime::camera::Camera;
use citywalk_runtime::oracle::{IdImage, Oracle};
use citywalk_runtime::scene_gpu::{SceneGeometry, SceneGpu};
use citywalk_shaders::{GROUND_ID, ID_BACKGROUND, ID_OFFSET, depth_tie_factor};
use citywalk_tests::city_builder::boxes;
use citywalk_tests::gpu::gpu_or_skip;
use glam::{Vec3, Vec3A, Vec4Swizzles};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;

/// A BVH over every triangle of the scene geometry (ground included), with the id-image value
/// each triangle writes and its building's depth tie factor.
struct RayScene {
    bvh: obvhs::bvh2::Bvh2,
    triangles: Vec<Triangle>,
    pixel_value: Vec<u32>,
    tie_factor: Vec<f32>,
}

impl RayScene {
    fn new(g: &SceneGeometry) -> RayScene {
        let mut triangles = Vec::new();
        let mut pixel_value = Vec::new();
        let mut tie_factor = Vec::new();
        let mut push = |base: i32, first: u32, count: u32| {
            for t in g.indices[first as usize..(first + count) as usize].chunks_exact(3) {
                let v = |i: u32| g.vertices[(base + i as i32) as usize];
                let id = v(t[0]).building_id;
                triangles.push(Triangle {
                    v0: Vec3A::from_array(v(t[0]).position_m),
                    v1: Vec3A::from_array(v(t[1]).position_m),
                    v2: Vec3A::from_array(v(t[2]).position_m),
                });
                tie_factor.push(depth_tie_factor(id));
                pixel_value.push(if id == GROUND_ID {
                    ID_BACKGROUND
                } else {
                    id + ID_OFFSET
                });
            }
        };
        for r in &g.records {
            push(r.base_vertex, r.first_index, r.index_count);
        }
        push(
            g.ground.base_vertex,
            g.ground.first_index,
            g.ground.index_count,
        );
        let mut build_time = std::time::Duration::ZERO;
        let bvh = obvhs::bvh2::builder::build_bvh2_from_tris(
            &triangles,
            obvhs::BvhBuildParams::medium_build(),
            &mut build_time,
        );
        RayScene {
            bvh,
            triangles,
            pixel_value,
            tie_factor,
        }
    }

    /// The id-image value seen through the centre of pixel `(x, y)`: that of the hit whose
    /// distance divided by its tie factor is least. The reversed-Z depth is `near / distance`
    /// along one ray, scaled by the factor, and the greatest wins: a hit farther than the best
    /// so far cannot win, so the traversal may prune with the divided distance.
    fn cast(&self, camera: &Camera, width: u32, height: u32, x: u32, y: u32) -> u32 {
        let inv = camera.view_proj(width as f32 / height as f32).inverse();
        let ndc_x = (x as f32 + 0.5) / width as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - (y as f32 + 0.5) / height as f32 * 2.0;
        // Reversed Z: NDC z = 1 is the near plane.
        let near = inv * glam::Vec4::new(ndc_x, ndc_y, 1.0, 1.0);
        let near: Vec3 = near.xyz() / near.w;
        let dir = (near - camera.position).normalize();
        let tmin = (near - camera.position).length();
        let ray = Ray::new(camera.position.into(), dir.into(), tmin, f32::INFINITY);
        let mut hit = RayHit::none();
        if self.bvh.ray_traverse(ray, &mut hit, |ray, i| {
            let t = self.bvh.primitive_indices[i] as usize;
            self.triangles[t].intersect(ray) / self.tie_factor[t]
        }) {
            self.pixel_value[self.bvh.primitive_indices[hit.primitive_id as usize] as usize]
        } else {
            ID_BACKGROUND
        }
    }
}

/// Whether the 3×3 neighbourhood of `(x, y)` in the id image holds more than one value.
fn on_edge(image: &IdImage, x: u32, y: u32) -> bool {
    let v = image.pixels[(y * image.width + x) as usize];
    (y.saturating_sub(1)..=(y + 1).min(image.height - 1)).any(|yy| {
        (x.saturating_sub(1)..=(x + 1).min(image.width - 1))
            .any(|xx| image.pixels[(yy * image.width + xx) as usize] != v)
    })
}

/// Compares the oracle's id image with ray casts at every `step`-th pixel; returns
/// (interior samples, interior mismatches, edge samples, interior samples showing a building).
fn cross_check(
    gpu: &citywalk_runtime::gpu::GpuContext,
    geometry: &SceneGeometry,
    camera: &Camera,
    (width, height): (u32, u32),
    step: u32,
) -> (usize, usize, usize, usize) {
    let scene = SceneGpu::upload(gpu, geometry).expect("the scene fits the GPU");
    let image = Oracle::new(gpu)
        .id_image(gpu, &scene, camera, width, height)
        .expect("id image");
    let rays = RayScene::new(geometry);
    let (mut interior, mut mismatches, mut edges, mut buildings) = (0, 0, 0, 0);
    for y in (0..height).step_by(step as usize) {
        for x in (0..width).step_by(step as usize) {
            if on_edge(&image, x, y) {
                edges += 1;
                continue;
            }
            interior += 1;
            let expected = rays.cast(camera, width, height, x, y);
            let got = image.pixels[(y * width + x) as usize];
            buildings += usize::from(got != ID_BACKGROUND);
            if expected != got {
                mismatches += 1;
                eprintln!("pixel ({x}, {y}): oracle {got}, ray cast {expected}");
            }
        }
    }
    (interior, mismatches, edges, buildings)
}

#[test]
fn oracle_agrees_with_ray_casting_on_a_box_grid() {
    let Some(gpu) = gpu_or_skip("oracle_agrees_with_ray_casting_on_a_box_grid") else {
        return;
    };
    // A 12 × 12 grid of boxes with deterministic pseudo-random sizes and heights.
    let mut specs = Vec::new();
    let mut state = 0x2545_f491_u32;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        f64::from(state % 1000) / 1000.0
    };
    for i in 0..12 {
        for j in 0..12 {
            let (x, y) = (f64::from(i) * 30.0, f64::from(j) * 30.0);
            let (w, d) = (8.0 + 16.0 * next(), 8.0 + 16.0 * next());
            specs.push((x, y, x + w, y + d, (4.0 + 50.0 * next()) as f32));
        }
    }
    // Every seventh box mapped twice, as OSM extracts have them: coplanar faces that the tie
    // rule settles (pairs whose levels differ, or the draw order would).
    let grid = specs.len();
    for i in (0..grid).step_by(7) {
        let twin = specs.len() as u32;
        assert_ne!(
            depth_tie_factor(i as u32),
            depth_tie_factor(twin),
            "boxes {i} and {twin} share a tie level"
        );
        specs.push(specs[i]);
    }
    let geometry = SceneGeometry::from_city(&boxes(&specs));
    let cameras = [
        Camera::new(
            Vec3::new(-20.0, -25.0, 1.7),
            40f32.to_radians(),
            2f32.to_radians(),
        ),
        Camera::new(
            Vec3::new(170.0, 160.0, 1.7),
            200f32.to_radians(),
            8f32.to_radians(),
        ),
        Camera::overview(geometry.bounds.0, geometry.bounds.1),
    ];
    for camera in &cameras {
        let (interior, mismatches, edges, buildings) =
            cross_check(&gpu, &geometry, camera, (333, 211), 3);
        eprintln!(
            "{}: {interior} interior samples, {mismatches} mismatches, {edges} on edges, {buildings} on buildings",
            camera.to_arg_string()
        );
        assert!(interior > 3000);
        assert!(
            buildings * 10 > interior,
            "only {buildings} building samples"
        );
        assert!(
            mismatches * 1000 <= interior,
            "{mismatches} of {interior} interior pixels disagree"
        );
    }
}
