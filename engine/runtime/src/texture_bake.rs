//! Bakes the cluster meshes' textures headless (Chang et al. 2008 §7): for every wall of a
//! cluster mesh, an orthographic view with its near plane on the wall, looking in, of the
//! cluster's buildings each scaled vertically to the cluster's height; for its roof, the five
//! roof views of the same buildings. Every view draws the cluster's buildings (a wall's, those
//! just behind it) into its rectangle of its page's view
//! ([`citywalk_scenes::cluster_texture::atlas`]): the buildings' triangles are laid out in the
//! tree's leaf order, so the buildings below a node are one index range. Where no building is seen the texture shows the bare ground. The
//! textures hold albedo: the runtime lights the cluster mesh itself.

use citywalk_scenes::cluster_texture::atlas::{
    AtlasView, BinCells, ClusterPlacement, ClusterWalls, layout_atlas,
};
use citywalk_scenes::cluster_texture::baked::{ClusterTextures, compress_page};
use citywalk_scenes::cluster_texture::roof_views::ViewFrame;
use citywalk_scenes::cluster_texture::side_layout::{BORDER_PX, FaceRect};
use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::extrude::extruded_walls;
use citywalk_scenes::package::GpuSceneView;
use citywalk_shaders::constants::BARE_GROUND_SRGB;
use citywalk_shaders::{BAKE_WGSL, BakeView};
use glam::{Mat4, Vec2, Vec3, Vec4};
use wgpu::util::DeviceExt;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::render::targets::{OffscreenTarget, ReadbackError};

/// The baked textures' format: albedo, 8 bits per channel, sRGB.
pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// Draws recorded in one render pass, their views in one storage buffer.
const DRAWS_PER_BATCH: usize = 16_384;

/// How far behind a wall its texture sees (m): the buildings standing farther in are not
/// drawn into it, and gaps that deep show the ground. A wall's texture shows the facades at
/// the cluster's edge; Chang et al. place the near plane on the face and leave the far plane
/// unsaid. 40 m is a deep city block's half.
pub const WALL_DEPTH_M: f32 = 40.0;

/// One view of a bake: its rectangle, its projection, and the index ranges drawn.
struct ViewDraw {
    rect: FaceRect,
    view: BakeView,
    ranges: Vec<(u32, u32)>,
}

/// Why a bake failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("the package has no cluster tree to texture")]
    NoTree,
    #[error("the cluster tree does not match the GPU scene: {0}")]
    Mismatch(String),
    #[error(transparent)]
    Readback(#[from] ReadbackError),
    #[error("cannot store the textures: {0}")]
    Store(String),
}

/// What a bake did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BakeStats {
    /// Cluster meshes textured, of `candidates`, those with walls (the rest have more walls
    /// than their cell holds).
    pub clusters: usize,
    pub candidates: usize,
    pub bins: usize,
    pub pages: usize,
    /// Draws (one per wall and per roof view of each cluster).
    pub draws: u64,
    pub texels: u64,
    pub compressed_bytes: u64,
    /// The whole bake, and the share of it spent compressing.
    pub seconds: f64,
    pub compress_seconds: f64,
}

/// The walls of every cluster mesh of `tree` that has them (inner nodes; leaves are drawn as
/// their buildings), with Chang's sort key, the negative-space area (Yang's Δa).
pub fn cluster_walls(tree: &ClusterTree) -> Vec<ClusterWalls> {
    tree.nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| !n.is_leaf())
        .filter_map(|(i, n)| {
            let (ring, base_m, top_m) = extruded_walls(&n.mesh)?;
            Some(ClusterWalls {
                node: i as u32,
                negative_space_m2: n.delta_a_m2,
                ring,
                base_m,
                top_m,
            })
        })
        .collect()
}

/// Bakes the textures of every cluster mesh of `tree` (its meshes present: a package decoded
/// whole, or fresh from preprocessing) whose buildings `scene` draws, at `bin_side_px²`
/// texels per bin and view.
pub fn bake_cluster_textures(
    gpu: &GpuContext,
    scene: &GpuSceneView<'_>,
    tree: &ClusterTree,
    bin_side_px: u32,
) -> Result<(ClusterTextures, BakeStats), BakeError> {
    let start = std::time::Instant::now();
    let walls = cluster_walls(tree);
    let layout = layout_atlas(&walls, bin_side_px);
    let baker = Baker::new(gpu, scene, tree)?;
    let mut images = Vec::with_capacity(layout.page_count as usize);
    let mut draws = 0u64;
    let mut compress_seconds = 0.0;
    let mut on_page: Vec<Vec<&ClusterPlacement>> = vec![Vec::new(); layout.page_count as usize];
    for p in &layout.clusters {
        on_page[p.page as usize].push(p);
    }
    for bin in &layout.bins {
        for page in bin.first_page..bin.first_page + bin.page_count {
            let mut views = Vec::with_capacity(AtlasView::ALL.len());
            for view in AtlasView::ALL {
                let placed = &on_page[page as usize];
                let (image, count) =
                    baker.render(gpu, layout.page_px, bin, placed, &walls, view)?;
                draws += count;
                views.push(image);
            }
            // Compressed at once: a bake holds one page of texels, not all of them.
            let compress_start = std::time::Instant::now();
            images.push(
                compress_page(layout.page_px, page as usize, &views).map_err(BakeError::Store)?,
            );
            compress_seconds += compress_start.elapsed().as_secs_f64();
        }
    }
    let textures =
        ClusterTextures::from_compressed(layout.clone(), images).map_err(BakeError::Store)?;
    let stats = BakeStats {
        clusters: layout.clusters.len(),
        candidates: walls.len(),
        bins: layout.bins.len(),
        pages: layout.page_count as usize,
        draws,
        texels: textures.texels(),
        compressed_bytes: textures.compressed_bytes(),
        seconds: start.elapsed().as_secs_f64(),
        compress_seconds,
    };
    Ok((textures, stats))
}

/// The GPU side of a bake: the buildings in leaf order, their tops, the pipeline.
struct Baker {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    tops: wgpu::Buffer,
    /// Per position in the tree's leaf order, where that building's indices start in
    /// `indices` (one more entry: the end).
    order_start: Vec<u32>,
    /// Per position in the leaf order, the building's plan bounds `[x0, y0, x1, y1]`.
    order_bounds: Vec<[f32; 4]>,
    /// Per node, its range of the leaf order.
    node_order: Vec<(u32, u32)>,
}

impl Baker {
    fn new(
        gpu: &GpuContext,
        scene: &GpuSceneView<'_>,
        tree: &ClusterTree,
    ) -> Result<Baker, BakeError> {
        let device = &gpu.device;
        let buildings = scene.building_count as usize;
        if tree.building_order.len() != buildings || scene.records.len() < buildings {
            return Err(BakeError::Mismatch(format!(
                "{} buildings in the tree's order, {buildings} in the scene",
                tree.building_order.len()
            )));
        }
        // The buildings' triangles in leaf order, their indices made absolute.
        let mut indices = Vec::new();
        let mut order_start = Vec::with_capacity(buildings + 1);
        let mut order_bounds = Vec::with_capacity(buildings);
        for id in &tree.building_order {
            order_start.push(indices.len() as u32);
            let r = scene.records.get(id.index()).ok_or_else(|| {
                BakeError::Mismatch(format!("building {} not in the scene", id.0))
            })?;
            order_bounds.push([
                r.bounds_min_m[0],
                r.bounds_min_m[1],
                r.bounds_max_m[0],
                r.bounds_max_m[1],
            ]);
            let range = r.first_index as usize..(r.first_index + r.index_count) as usize;
            let source = scene.indices.get(range).ok_or_else(|| {
                BakeError::Mismatch(format!("building {}: index range out of bounds", id.0))
            })?;
            indices.extend(
                source
                    .iter()
                    .map(|&i| (i as i64 + i64::from(r.base_vertex)) as u32),
            );
        }
        order_start.push(indices.len() as u32);
        let node_order = tree
            .nodes
            .iter()
            .map(|n| {
                let (a, b) = n.buildings;
                if a <= b && (b as usize) < order_start.len() {
                    Ok((a, b))
                } else {
                    Err(BakeError::Mismatch(format!("node buildings {a}..{b}")))
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        let tops: Vec<f32> = scene.records[..buildings]
            .iter()
            .map(|r| r.bounds_max_m[2])
            .collect();
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        // Empty buffers are not allowed; a city of no triangles still binds one element.
        let vertices = init(
            "bake vertices",
            bytemuck::cast_slice(if scene.vertices.is_empty() {
                &[0u8; 16][..]
            } else {
                bytemuck::cast_slice(scene.vertices)
            }),
            wgpu::BufferUsages::VERTEX,
        );
        indices.push(0);
        let indices = init(
            "bake indices",
            bytemuck::cast_slice(&indices),
            wgpu::BufferUsages::INDEX,
        );
        let mut tops = tops;
        tops.push(0.0);
        let tops = init(
            "bake building tops",
            bytemuck::cast_slice(&tops),
            wgpu::BufferUsages::STORAGE,
        );
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("bake"),
            entries: &[storage(0), storage(1)],
        });
        let pipeline = crate::render::scene_pipeline_with(
            device,
            "cluster texture bake",
            BAKE_WGSL,
            &layout,
            (Camera::DEPTH_COMPARE, true),
            Some(wgpu::ColorTargetState {
                format: FORMAT,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            }),
        );
        Ok(Baker {
            pipeline,
            layout,
            vertices,
            indices,
            tops,
            order_start,
            order_bounds,
            node_order,
        })
    }

    /// Renders `view` of the clusters `placed` on one page (of `page_px` texels on a side) of
    /// `bin`, fills the rectangles' borders and returns the texels (RGBA8) and the number of
    /// draws.
    fn render(
        &self,
        gpu: &GpuContext,
        page_px: u32,
        bin: &BinCells,
        placed: &[&ClusterPlacement],
        walls: &[ClusterWalls],
        view: AtlasView,
    ) -> Result<(Vec<u8>, u64), BakeError> {
        let target = OffscreenTarget::new(gpu, page_px, page_px, FORMAT)?;
        let mut views: Vec<ViewDraw> = Vec::new();
        for p in placed {
            let (first, end) = self.node_order[p.node as usize];
            match view {
                AtlasView::Side => {
                    // `walls` is in node order, as `cluster_walls` lists them.
                    let Ok(at) = walls.binary_search_by_key(&p.node, |w| w.node) else {
                        continue;
                    };
                    let ring = &walls[at].ring;
                    for face in 0..p.sides.faces.len() {
                        let Some(rect) = p.face_rect_px(bin, face) else {
                            continue;
                        };
                        let (a, b) = (ring[face], ring[(face + 1) % ring.len()]);
                        views.push(ViewDraw {
                            rect,
                            view: wall_view(p, a, b),
                            ranges: self.behind_wall(first..end, a, b),
                        });
                    }
                }
                AtlasView::Roof(roof) => {
                    let frame = roof.frame(Vec3::from(p.box_lo_m), Vec3::from(p.box_hi_m));
                    views.push(ViewDraw {
                        rect: p.roof_rect_px(bin),
                        view: frame_view(p, &frame),
                        ranges: vec![self.index_range(first..end)],
                    });
                }
            }
        }
        let mut first = true;
        let mut batch_start = 0;
        let mut batch_draws = 0;
        for (i, v) in views.iter().enumerate() {
            batch_draws += v.ranges.len();
            if batch_draws >= DRAWS_PER_BATCH || i + 1 == views.len() {
                self.draw_batch(gpu, &target, &views[batch_start..=i], first);
                (first, batch_start, batch_draws) = (false, i + 1, 0);
            }
        }
        if first {
            // Nothing to draw: the texture is all ground.
            self.draw_batch(gpu, &target, &[], true);
        }
        let mut texels = target.read_colour(gpu)?;
        let rects: Vec<FaceRect> = views.iter().map(|d| d.rect).collect();
        fill_borders(&mut texels, page_px, &rects);
        let draws = views.iter().map(|v| v.ranges.len() as u64).sum();
        Ok((texels, draws))
    }

    /// The index range of the buildings at `order` positions of the leaf order.
    fn index_range(&self, order: std::ops::Range<u32>) -> (u32, u32) {
        (
            self.order_start[order.start as usize],
            self.order_start[order.end as usize],
        )
    }

    /// The index ranges of the buildings at `order` positions whose plan bounds reach into the
    /// slab behind the wall from `a` to `b`: along the wall, and up to [`WALL_DEPTH_M`] in
    /// (the wall's far plane). Neighbours in the leaf order are neighbours in the city, so the
    /// buildings found make few ranges.
    fn behind_wall(
        &self,
        order: std::ops::Range<u32>,
        a: [f32; 2],
        b: [f32; 2],
    ) -> Vec<(u32, u32)> {
        let (a, b) = (Vec2::from(a), Vec2::from(b));
        let length = (b - a).length();
        let along = (b - a) / length.max(1e-6);
        let inward = Vec2::new(-along.y, along.x);
        let mut ranges: Vec<(u32, u32)> = Vec::new();
        for k in order {
            let [x0, y0, x1, y1] = self.order_bounds[k as usize];
            let corners = [
                Vec2::new(x0, y0),
                Vec2::new(x1, y0),
                Vec2::new(x0, y1),
                Vec2::new(x1, y1),
            ];
            let span = |axis: Vec2| {
                corners.iter().fold((f32::MAX, f32::MIN), |(lo, hi), c| {
                    let t = (*c - a).dot(axis);
                    (lo.min(t), hi.max(t))
                })
            };
            let (s, t) = (span(along), span(inward));
            if s.1 < 0.0 || s.0 > length || t.1 < 0.0 || t.0 > WALL_DEPTH_M {
                continue;
            }
            let (start, end) = (
                self.order_start[k as usize],
                self.order_start[k as usize + 1],
            );
            match ranges.last_mut() {
                Some(last) if last.1 == start => last.1 = end,
                _ => ranges.push((start, end)),
            }
        }
        ranges
    }

    fn draw_batch(
        &self,
        gpu: &GpuContext,
        target: &OffscreenTarget,
        batch: &[ViewDraw],
        clear: bool,
    ) {
        let device = &gpu.device;
        let views: Vec<BakeView> = if batch.is_empty() {
            vec![bytemuck::Zeroable::zeroed()]
        } else {
            batch.iter().map(|d| d.view).collect()
        };
        let views = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("bake views"),
            contents: bytemuck::cast_slice(&views),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bake"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: views.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: self.tops.as_entire_binding(),
                },
            ],
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bake"),
        });
        {
            let ground = bare_ground_linear();
            let load = if clear {
                wgpu::LoadOp::Clear(wgpu::Color {
                    r: ground.x,
                    g: ground.y,
                    b: ground.z,
                    a: 1.0,
                })
            } else {
                wgpu::LoadOp::Load
            };
            let depth = if clear {
                target.depth.attachment()
            } else {
                target.depth.loaded_attachment()
            };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("bake"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.colour_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load,
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(depth),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
            for (k, draw) in batch.iter().enumerate() {
                if draw.ranges.iter().all(|(first, end)| first == end) {
                    continue;
                }
                let rect = &draw.rect;
                pass.set_viewport(
                    rect.x_px as f32,
                    rect.y_px as f32,
                    rect.width_px as f32,
                    rect.height_px as f32,
                    0.0,
                    1.0,
                );
                pass.set_scissor_rect(rect.x_px, rect.y_px, rect.width_px, rect.height_px);
                let k = k as u32;
                for &(first, end) in &draw.ranges {
                    pass.draw_indexed(first..end, 0, k..k + 1);
                }
            }
        }
        gpu.queue.submit([encoder.finish()]);
    }
}

/// The bare ground's colour in linear RGB, as `bare_ground_colour` in the shaders (the
/// clear colour of an sRGB target is given in linear values).
fn bare_ground_linear() -> glam::DVec3 {
    glam::DVec3::from(BARE_GROUND_SRGB.map(f64::from)).powf(2.2)
}

/// How far in front of what it must see each view's near plane lies (m): a building scaled to
/// the roof, or a facade on the hull's edge, lands a few ulp off its plane, and a point just
/// past the near plane would be clipped away.
const NEAR_SLACK_M: f32 = 0.01;

/// The orthographic view of the wall from `a` to `b` (the hull counter-clockwise, the cluster
/// on the wall's left): looking in from the wall, `a` at the image's left, the walls' foot at
/// the bottom and the roof at the top; the near plane on the wall (what stands outside it is
/// clipped), the far plane [`WALL_DEPTH_M`] in.
fn wall_view(p: &ClusterPlacement, a: [f32; 2], b: [f32; 2]) -> BakeView {
    let (a, b) = (Vec2::from(a), Vec2::from(b));
    let length = (b - a).length().max(1e-6);
    let along = (b - a) / length;
    let outward = Vec2::new(along.y, -along.x);
    let (lo, hi) = (Vec3::from(p.box_lo_m), Vec3::from(p.box_hi_m));
    let height = (hi.z - lo.z).max(1e-3);
    // Reversed Z: 1 just outside the wall, falling to 0 at `WALL_DEPTH_M` in.
    let depth = WALL_DEPTH_M + NEAR_SLACK_M;
    let rows = [
        Vec4::new(
            2.0 * along.x / length,
            2.0 * along.y / length,
            0.0,
            -2.0 * a.dot(along) / length - 1.0,
        ),
        Vec4::new(0.0, 0.0, 2.0 / height, -2.0 * lo.z / height - 1.0),
        Vec4::new(
            outward.x / depth,
            outward.y / depth,
            0.0,
            1.0 - (a.dot(outward) + NEAR_SLACK_M) / depth,
        ),
        Vec4::W,
    ];
    bake_view(rows, hi.z)
}

/// The orthographic roof view `frame` of the cluster's box, filling the image as
/// [`ViewFrame::uv`] reads it (an axis of no extent maps to the image's middle).
fn frame_view(p: &ClusterPlacement, frame: &ViewFrame) -> BakeView {
    // Clip x or y of axis `k`: -1 at the range's start, +1 at its end.
    let image_row = |k: usize| {
        let (min, max) = frame.ranges[k];
        if max > min {
            let extent = max - min;
            (2.0 * frame.axes[k] / extent).extend(-2.0 * min / extent - 1.0)
        } else {
            Vec4::ZERO
        }
    };
    // Reversed Z: 1 just before the box's nearest corner, 0 just past its farthest.
    let (near, far) = (
        frame.ranges[2].0 - NEAR_SLACK_M,
        frame.ranges[2].1 + NEAR_SLACK_M,
    );
    let ahead = frame.axes[2];
    let rows = [
        image_row(0),
        // v grows down the image, clip y up.
        -image_row(1),
        (-ahead / (far - near)).extend(1.0 + near / (far - near)),
        Vec4::W,
    ];
    bake_view(rows, p.box_hi_m[2])
}

fn bake_view(rows: [Vec4; 4], roof_m: f32) -> BakeView {
    let world_to_clip = Mat4::from_cols(rows[0], rows[1], rows[2], rows[3]).transpose();
    BakeView {
        world_to_clip: world_to_clip.to_cols_array_2d(),
        params: [roof_m, 0.0, 0.0, 0.0],
    }
}

/// Fills the border of each rectangle (its [`BORDER_PX`] texels all round) with the
/// rectangle's nearest texel, so that filtering at its edge reads its own colours.
fn fill_borders(texels: &mut [u8], width_px: u32, rects: &[FaceRect]) {
    let height_px = (texels.len() / 4) as u32 / width_px.max(1);
    let b = BORDER_PX as i64;
    for r in rects {
        let (x0, y0) = (i64::from(r.x_px), i64::from(r.y_px));
        let (x1, y1) = (
            x0 + i64::from(r.width_px) - 1,
            y0 + i64::from(r.height_px) - 1,
        );
        for y in y0 - b..=y1 + b {
            for x in x0 - b..=x1 + b {
                let inside = (x0..=x1).contains(&x) && (y0..=y1).contains(&y);
                if inside || x < 0 || y < 0 || x >= i64::from(width_px) || y >= i64::from(height_px)
                {
                    continue;
                }
                let (sx, sy) = (x.clamp(x0, x1), y.clamp(y0, y1));
                let from = ((sy * i64::from(width_px) + sx) * 4) as usize;
                let to = ((y * i64::from(width_px) + x) * 4) as usize;
                texels.copy_within(from..from + 4, to);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use citywalk_scenes::cluster_texture::roof_views::RoofView;
    use citywalk_scenes::cluster_texture::side_layout::SideLayout;

    fn placement(lo: [f32; 3], hi: [f32; 3]) -> ClusterPlacement {
        ClusterPlacement {
            node: 0,
            bin: 0,
            page: 0,
            cell: 0,
            sides: SideLayout {
                side_px: 64,
                texels_per_m: 1.0,
                faces: Vec::new(),
            },
            box_lo_m: lo,
            box_hi_m: hi,
        }
    }

    fn clip(view: &BakeView, p: Vec3) -> Vec3 {
        let c = Mat4::from_cols_array_2d(&view.world_to_clip) * p.extend(1.0);
        c.truncate() / c.w
    }

    /// CPU reference of the roof views: where the baked view puts a point is where
    /// `ViewFrame::uv` (what the runtime will sample) reads it, and the box lies inside the
    /// depth range.
    #[test]
    fn roof_views_put_each_point_where_its_texture_coordinate_reads_it() {
        let p = placement([-12.0, 4.0, 0.0], [30.0, 19.0, 14.0]);
        let (lo, hi) = (Vec3::from(p.box_lo_m), Vec3::from(p.box_hi_m));
        for view in RoofView::ALL {
            let frame = view.frame(lo, hi);
            let bake = frame_view(&p, &frame);
            for t in [
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
                [0.3, 0.8, 1.0],
                [0.9, 0.1, 0.0],
            ] {
                let point = lo + (hi - lo) * Vec3::from(t);
                let c = clip(&bake, point);
                let [u, v] = frame.uv(point);
                assert!(
                    (u - (c.x + 1.0) / 2.0).abs() < 1e-4,
                    "{view:?} {t:?}: {c} {u}"
                );
                assert!(
                    (v - (1.0 - c.y) / 2.0).abs() < 1e-4,
                    "{view:?} {t:?}: {c} {v}"
                );
                assert!(c.z > 0.0 && c.z < 1.0, "{view:?} {t:?}: depth {}", c.z);
            }
        }
        // A box of no extent across the view: its middle, as `uv` says.
        let flat = placement([3.0, 3.0, 0.0], [3.0, 3.0, 0.0]);
        let frame = RoofView::Top.frame(Vec3::splat(3.0), Vec3::splat(3.0));
        let c = clip(&frame_view(&flat, &frame), Vec3::new(3.0, 3.0, 0.0));
        assert_eq!((c.x, c.y), (0.0, 0.0));
    }

    #[test]
    fn a_wall_view_spans_the_wall_and_sees_its_plane() {
        let p = placement([0.0, 0.0, 2.0], [20.0, 10.0, 12.0]);
        // The south wall of a counter-clockwise ring runs east; the cluster is to its north.
        let view = wall_view(&p, [0.0, 0.0], [20.0, 0.0]);
        let foot_left = clip(&view, Vec3::new(0.0, 0.0, 2.0));
        let top_right = clip(&view, Vec3::new(20.0, 0.0, 12.0));
        assert!((foot_left - Vec3::new(-1.0, -1.0, foot_left.z)).length() < 1e-5);
        assert!((top_right - Vec3::new(1.0, 1.0, top_right.z)).length() < 1e-5);
        // The wall's own plane is inside the near plane, the far plane 40 m in, the outside
        // beyond the near plane.
        assert!(foot_left.z < 1.0 && foot_left.z > 0.999);
        let deep = clip(&view, Vec3::new(10.0, WALL_DEPTH_M - 0.1, 5.0));
        assert!(deep.z > 0.0 && deep.z < 0.01, "{deep}");
        assert!(clip(&view, Vec3::new(10.0, WALL_DEPTH_M + 1.0, 5.0)).z < 0.0);
        assert!(clip(&view, Vec3::new(10.0, -1.0, 5.0)).z > 1.0);
    }

    #[test]
    fn borders_repeat_their_rectangles_edge() {
        // A 6 × 5 page, one 2 × 2 rectangle at (2, 1) of four colours.
        let (w, h) = (6u32, 5u32);
        let mut texels = vec![0u8; (w * h * 4) as usize];
        let put = |t: &mut Vec<u8>, x: u32, y: u32, v: u8| t[((y * w + x) * 4) as usize] = v;
        let get = |t: &Vec<u8>, x: u32, y: u32| t[((y * w + x) * 4) as usize];
        put(&mut texels, 2, 1, 10);
        put(&mut texels, 3, 1, 20);
        put(&mut texels, 2, 2, 30);
        put(&mut texels, 3, 2, 40);
        let rect = FaceRect {
            x_px: 2,
            y_px: 1,
            width_px: 2,
            height_px: 2,
        };
        fill_borders(&mut texels, w, &[rect]);
        let rows: Vec<Vec<u8>> = (0..h)
            .map(|y| (0..w).map(|x| get(&texels, x, y)).collect())
            .collect();
        assert_eq!(
            rows,
            [
                [0, 10, 10, 20, 20, 0],
                [0, 10, 10, 20, 20, 0],
                [0, 30, 30, 40, 40, 0],
                [0, 30, 30, 40, 40, 0],
                [0, 0, 0, 0, 0, 0],
            ]
        );
    }
}
