//! The ground-surface pass: streets, water, parks and squares drawn over the ground plane after
//! the frame's scene passes, whatever the plan.
//!
//! * **Never an occluder.** The pass tests depth and writes none, so the surfaces neither hide
//!   a building from the hierarchical-Z pyramid nor enter the visibility oracle (which draws
//!   buildings only); a building in front of a street still covers it. They lie a centimetre
//!   or so above the ground plane, so they pass the depth test over it without fighting;
//!   overlapping surfaces (a street's pieces, a crossing) draw in layer order, last on top.
//! * **Distance LOD.** A draw (one layer in one chunk, [`GroundSurfaces`]) is drawn while its
//!   narrowest feature projects to at least [`SURFACE_MIN_PX`] pixels at the nearest point of
//!   its bounds: far away only the major roads and large areas remain. The selection is made
//!   on the CPU with a margin and kept while the eye stays within it, so most frames do no
//!   per-draw work; a new selection writes one indirect-draw list (consecutive draws merged).

use std::cell::Cell;

use citywalk_scenes::ground_surfaces::GroundSurfaces;
use citywalk_shaders::{DrawIndexedIndirectArgs, SCENE_WGSL, SURFACE_ID_BASE, SceneVertex};
use glam::{Vec2, Vec3};

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::render::targets::DepthTarget;
use crate::render::view::{SceneStyle, view_uniforms};
use crate::upload::{UploadError, array_buffer};

/// A surface draw is skipped where its narrowest feature projects below this many pixels: the
/// building LOD's default tolerance (1 px), so dropping it changes no more than a pixel's band.
pub const SURFACE_MIN_PX: f32 = 1.0;

/// How far above the ground plane the surfaces lie (metres), and the extra lift per layer: far
/// above the depth buffer's resolution wherever the LOD draws them (reversed-Z float; the depth
/// step is about lift ÷ eye height of the depth), yet a wall standing on a street loses at most
/// its bottom 1.6 cm to the street (at most a pixel row along its foot).
const LIFT_M: f32 = 0.01;
const LIFT_PER_LAYER_M: f32 = 0.0005;

/// The selection is remade once the eye has moved this far (metres) or this share of its
/// height above the ground, whichever is more; the draws within the cut-off distance plus this
/// margin are selected, so every draw the LOD wants is in it until then.
const RESELECT_MARGIN_M: f32 = 32.0;
const RESELECT_MARGIN_OF_HEIGHT: f32 = 0.05;

/// The ground surfaces on the GPU and their current LOD selection.
#[derive(Debug)]
pub struct SurfaceMeshes {
    vertex_buffer: wgpu::Buffer,
    index_buffer: wgpu::Buffer,
    /// The package's draws (CPU copy, for the selection).
    draws: Vec<Draw>,
    indirect: wgpu::Buffer,
    /// The current selection (a cell: frames draw through shared references to the scene).
    selection: Cell<Option<Selection>>,
    ground_z: f32,
}

/// The pass drawing [`SurfaceMeshes`] into colour targets of one format.
#[derive(Debug)]
pub struct GroundSurfacePass {
    pipeline: wgpu::RenderPipeline,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
}

/// One draw's range and what the LOD tests.
#[derive(Debug, Clone, Copy)]
struct Draw {
    first_index: u32,
    index_count: u32,
    min: Vec2,
    max: Vec2,
    feature_m: f32,
}

/// The draws selected for eyes within `margin_m` of `eye`, at `focal_px`.
#[derive(Debug, Clone, Copy)]
struct Selection {
    eye: Vec3,
    margin_m: f32,
    focal_px: f32,
    /// Indirect draws written.
    count: u32,
    /// Draws selected (before merging), for the report.
    draws: u32,
    triangles: u64,
}

/// What the pass drew in a frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SurfaceStats {
    /// Surface draws (layer × chunk) drawn.
    pub draws: u32,
    pub triangles: u64,
}

impl SurfaceMeshes {
    /// Uploads `surfaces` to lie just above the ground plane at height `ground_z`. `None` when
    /// there is nothing to draw.
    pub fn upload(
        gpu: &GpuContext,
        surfaces: &GroundSurfaces,
        ground_z: f32,
    ) -> Result<Option<SurfaceMeshes>, UploadError> {
        if surfaces.draws.is_empty() {
            return Ok(None);
        }
        // A package's section was checked when it was read; a caller's own surfaces may not be.
        surfaces
            .check()
            .map_err(|message| UploadError::Inconsistent {
                what: "ground surfaces".into(),
                message,
            })?;
        // Each vertex takes the layer of the draw it belongs to (draws never share vertices).
        let mut vertices: Vec<SceneVertex> = surfaces
            .vertices
            .iter()
            .map(|&[x, y]| SceneVertex {
                position_m: [x, y, ground_z + LIFT_M],
                building_id: SURFACE_ID_BASE,
            })
            .collect();
        for d in &surfaces.draws {
            let range = d.first_index as usize..(d.first_index + d.index_count) as usize;
            for &i in &surfaces.indices[range] {
                if let Some(v) = vertices.get_mut(i as usize) {
                    v.building_id = SURFACE_ID_BASE + d.layer;
                    v.position_m[2] = ground_z + LIFT_M + LIFT_PER_LAYER_M * d.layer as f32;
                }
            }
        }
        use wgpu::BufferUsages as U;
        let keep = &|_: &[u8]| {};
        let vertex_buffer =
            array_buffer(gpu, "ground surface vertices", &vertices, U::VERTEX, keep)?;
        let index_buffer = array_buffer(
            gpu,
            "ground surface indices",
            &surfaces.indices,
            U::INDEX,
            keep,
        )?;
        let draws: Vec<Draw> = surfaces
            .draws
            .iter()
            .map(|d| Draw {
                first_index: d.first_index,
                index_count: d.index_count,
                min: Vec2::from(d.min_m),
                max: Vec2::from(d.max_m),
                feature_m: d.feature_m,
            })
            .collect();
        let indirect = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ground surface draws"),
            size: (draws.len() * size_of::<DrawIndexedIndirectArgs>()) as u64,
            usage: U::INDIRECT | U::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(Some(SurfaceMeshes {
            vertex_buffer,
            index_buffer,
            draws,
            indirect,
            selection: Cell::new(None),
            ground_z,
        }))
    }

    /// Surface draws in all.
    pub fn draw_count(&self) -> usize {
        self.draws.len()
    }

    /// The selection for `camera` at a viewport `height_px` high: the current one while the
    /// eye stays within its margin, else a new one written to the indirect buffer.
    fn select(&self, gpu: &GpuContext, camera: &Camera, height_px: u32) -> Selection {
        let focal_px = height_px.max(1) as f32 / (2.0 * (camera.fov_y_rad / 2.0).tan());
        let eye = camera.position;
        if let Some(s) = self.selection.get()
            && s.focal_px == focal_px
            && s.eye.distance(eye) <= s.margin_m
        {
            return s;
        }
        let height = (eye.z - self.ground_z).abs();
        let margin_m = RESELECT_MARGIN_M.max(RESELECT_MARGIN_OF_HEIGHT * height);
        let (args, draws, triangles) =
            selected_draws(&self.draws, eye, self.ground_z, focal_px, margin_m);
        if !args.is_empty() {
            gpu.queue
                .write_buffer(&self.indirect, 0, bytemuck::cast_slice(&args));
        }
        let selection = Selection {
            eye,
            margin_m,
            focal_px,
            count: args.len() as u32,
            draws,
            triangles,
        };
        self.selection.set(Some(selection));
        selection
    }
}

/// The draws of `draws` whose narrowest feature projects to [`SURFACE_MIN_PX`] or more, at
/// `focal_px`, for some eye within `margin_m` of `eye` (the ground at `ground_z`): as indirect
/// draws, consecutive ranges merged, with the number of draws and triangles selected.
fn selected_draws(
    draws: &[Draw],
    eye: Vec3,
    ground_z: f32,
    focal_px: f32,
    margin_m: f32,
) -> (Vec<DrawIndexedIndirectArgs>, u32, u64) {
    let mut args: Vec<DrawIndexedIndirectArgs> = Vec::new();
    let (mut count, mut triangles) = (0, 0);
    for d in draws {
        let cut_off_m = d.feature_m * focal_px / SURFACE_MIN_PX;
        let nearest = eye.truncate().clamp(d.min, d.max).extend(ground_z);
        if eye.distance(nearest) > cut_off_m + margin_m {
            continue;
        }
        count += 1;
        triangles += u64::from(d.index_count / 3);
        match args.last_mut() {
            Some(last) if last.first_index + last.index_count == d.first_index => {
                last.index_count += d.index_count;
            }
            _ => args.push(DrawIndexedIndirectArgs {
                index_count: d.index_count,
                instance_count: 1,
                first_index: d.first_index,
                base_vertex: 0,
                first_instance: 0,
            }),
        }
    }
    (args, count, triangles)
}

impl GroundSurfacePass {
    /// The pass for colour targets of `colour_format`.
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> GroundSurfacePass {
        let device = &gpu.device;
        let layout = super::view_bind_group_layout(device, "ground surface view");
        let (view_buffer, view_group) =
            super::view_buffer_and_group(device, &layout, "ground surface view");
        let colour = wgpu::ColorTargetState {
            format: colour_format,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        };
        let pipeline = super::scene_pipeline_with(
            device,
            "ground surfaces",
            SCENE_WGSL,
            &layout,
            (Camera::DEPTH_COMPARE, false),
            Some(colour),
        );
        GroundSurfacePass {
            pipeline,
            view_buffer,
            view_group,
        }
    }

    /// Records the pass of `meshes` over a frame already drawn into `colour` and `depth` (both loaded and
    /// kept; depth is only tested) for `camera`, with the look `style`.
    pub fn encode(
        &self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        meshes: &SurfaceMeshes,
        camera: &Camera,
        (colour, depth): (&wgpu::TextureView, &DepthTarget),
        style: &SceneStyle,
    ) -> SurfaceStats {
        let selection = meshes.select(gpu, camera, depth.height);
        let stats = SurfaceStats {
            draws: selection.draws,
            triangles: selection.triangles,
        };
        if selection.count == 0 {
            return stats;
        }
        let uniforms = view_uniforms(camera, depth.width, depth.height, style);
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let mut pass = super::overlay_pass(encoder, "ground surfaces", colour, depth, None);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        pass.set_vertex_buffer(0, meshes.vertex_buffer.slice(..));
        pass.set_index_buffer(meshes.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        pass.multi_draw_indexed_indirect(&meshes.indirect, 0, selection.count);
        stats
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn draw(first_index: u32, x: f32, feature_m: f32) -> Draw {
        Draw {
            first_index,
            index_count: 6,
            min: Vec2::new(x, 0.0),
            max: Vec2::new(x + 100.0, 100.0),
            feature_m,
        }
    }

    #[test]
    fn far_away_only_wide_features_are_drawn_and_near_ones_merge() {
        // A footway (3 m), a residential street (7 m) and a major road (14 m) side by side, then
        // a major road elsewhere; a 720 px high view with a 60° field of view.
        let draws = [
            draw(0, 0.0, 3.0),
            draw(6, 0.0, 7.0),
            draw(12, 0.0, 14.0),
            draw(30, 5000.0, 14.0),
        ];
        let focal_px = 720.0 / (2.0 * (30f32.to_radians()).tan());
        let near = Vec3::new(50.0, 50.0, 1.7);
        let (args, count, triangles) = selected_draws(&draws, near, 0.0, focal_px, 32.0);
        // All four: the far major road (5 km) still projects to 14 × 623 / 4900 ≈ 1.8 px.
        assert_eq!(count, 4);
        assert_eq!(triangles, 8);
        // The three adjacent ranges merge into one indirect draw.
        assert_eq!(args.len(), 2);
        assert_eq!((args[0].first_index, args[0].index_count), (0, 18));
        // 4 km from the first group: the footway (3 m → 0.5 px) and the street (7 m → 1.1 px
        // at 4 km, dropped at 4.4 km) go, the major road stays.
        let far = Vec3::new(4_500.0 + 100.0, 50.0, 1.7);
        let (args, count, _) = selected_draws(&draws, far, 0.0, focal_px, 32.0);
        assert_eq!(count, 2, "{args:?}");
        assert!(
            args.iter()
                .all(|a| a.first_index == 12 || a.first_index == 30)
        );
    }

    #[test]
    fn the_margin_keeps_a_selection_valid_while_the_eye_moves_within_it() {
        // Whatever the eye does within the margin, a draw the LOD wants there was selected.
        let draws: Vec<Draw> = (0..40)
            .map(|k| draw(6 * k, 150.0 * k as f32, 2.0 + (k % 5) as f32 * 3.0))
            .collect();
        let focal_px = 500.0;
        let margin = 32.0;
        for start_x in [0.0f32, 1_000.0, 3_333.0] {
            let start = Vec3::new(start_x, -200.0, 2.0);
            for step in 0..=8 {
                let eye =
                    start + Vec3::new(step as f32 * margin / 8.0 * 0.7, step as f32 * 2.0, 0.0);
                assert!(eye.distance(start) <= margin);
                for d in &draws {
                    let nearest = eye.truncate().clamp(d.min, d.max).extend(0.0);
                    let wanted = d.feature_m * focal_px / eye.distance(nearest) >= SURFACE_MIN_PX;
                    let selected =
                        selected_draws(std::slice::from_ref(d), start, 0.0, focal_px, margin).1
                            == 1;
                    assert!(!wanted || selected, "draw at {:?} from {eye}", d.min);
                }
            }
        }
    }
}
