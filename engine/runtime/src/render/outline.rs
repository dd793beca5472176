//! The outline of a picked building or cluster mesh: its feature edges (every edge whose two
//! faces meet at more than [`CREASE_DEG`], every edge of one face only) built once on the CPU
//! from the draw's triangles ([`feature_edges`]), uploaded as a line list and drawn after each
//! frame into its colour, depth-tested against the frame's depth and pulled a little towards
//! the eye (`wgsl/outline.wgsl`), so the edges the user sees show and those behind other
//! buildings do not. The tint of the picked draw ([`super::SceneStyle::highlight`]) stays:
//! the outline draws its shape, the tint which surfaces are its.

use std::collections::HashMap;

use citywalk_shaders::{OUTLINE_WGSL, SceneVertex};
use glam::Vec3;
use wgpu::util::DeviceExt;

use super::{DepthTarget, SceneStyle, view_bind_group_layout, view_buffer_and_group};
use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::pick::{PickGeometry, draw_triangles};
use crate::scene_gpu::SCENE_VERTEX_LAYOUT;

/// Two faces meeting at an edge at more than this (degrees) make it a feature edge. Flat roofs
/// and walls meet at 90°; a triangulated plane's inner edges at 0°; 20° keeps the folds of a
/// pitched roof or a simplified cluster mesh and drops the facets of a curved one finer than
/// that.
pub const CREASE_DEG: f32 = 20.0;

/// The feature edges of draw `draw` of `geometry`, two vertices per edge (positions in metres,
/// the id the draw's). Vertices are welded by position, since a flat-shaded mesh repeats them
/// per face; face normals are compared without their sign, since meshes from files mix
/// windings. An edge of more than two faces is kept too. Empty for a draw out of range.
pub fn feature_edges(geometry: PickGeometry<'_>, draw: u32) -> Vec<SceneVertex> {
    let cos_crease = CREASE_DEG.to_radians().cos();
    let mut welded: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions: Vec<Vec3> = Vec::new();
    let mut weld = |p: Vec3| -> u32 {
        *welded
            .entry(p.to_array().map(f32::to_bits))
            .or_insert_with(|| {
                positions.push(p);
                positions.len() as u32 - 1
            })
    };
    /// The first face's normal, how many faces share the edge, and whether two of them fold.
    struct Faces {
        normal: Vec3,
        count: u32,
        folded: bool,
    }
    let mut edges: HashMap<(u32, u32), Faces> = HashMap::new();
    for [a, b, c] in draw_triangles(geometry, draw) {
        let Some(normal) = (b - a).cross(c - a).try_normalize() else {
            continue; // Degenerate: no face to border.
        };
        let corners = [weld(a), weld(b), weld(c)];
        for k in 0..3 {
            let (i, j) = (corners[k], corners[(k + 1) % 3]);
            let faces = edges.entry((i.min(j), i.max(j))).or_insert(Faces {
                normal,
                count: 0,
                folded: false,
            });
            faces.folded |= faces.normal.dot(normal).abs() < cos_crease;
            faces.count += 1;
        }
    }
    let mut kept: Vec<(u32, u32)> = edges
        .into_iter()
        .filter(|(_, f)| f.count != 2 || f.folded)
        .map(|(edge, _)| edge)
        .collect();
    kept.sort_unstable();
    kept.into_iter()
        .flat_map(|(i, j)| [i, j])
        .map(|i| SceneVertex {
            position_m: positions[i as usize].to_array(),
            building_id: draw,
        })
        .collect()
}

/// The outline's lines on the GPU.
#[derive(Debug)]
struct Lines {
    buffer: wgpu::Buffer,
    vertex_count: u32,
}

/// The outline pass: its pipeline, view uniforms and the lines of the draw it outlines.
#[derive(Debug)]
pub struct OutlineRenderer {
    pipeline: wgpu::RenderPipeline,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    /// The draw outlined and its lines (`None` when it has no edges).
    outlined: Option<(u32, Option<Lines>)>,
}

impl OutlineRenderer {
    /// An outline pass drawing into colour targets of `colour_format` over a
    /// [`DepthTarget`] the frame filled.
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> OutlineRenderer {
        let device = &gpu.device;
        let layout = view_bind_group_layout(device, "outline view");
        let (view_buffer, view_group) = view_buffer_and_group(device, &layout, "outline view");
        let (module, pipeline_layout) =
            super::module_and_layout(device, "outline", OUTLINE_WGSL, &layout);
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("outline"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(SCENE_VERTEX_LAYOUT)],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::LineList,
                ..Default::default()
            },
            // Tested, not written: the lines lie over the frame's surfaces.
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DepthTarget::FORMAT,
                depth_write_enabled: Some(false),
                depth_compare: Some(Camera::DEPTH_COMPARE),
                stencil: wgpu::StencilState::default(),
                bias: wgpu::DepthBiasState::default(),
            }),
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: colour_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        OutlineRenderer {
            pipeline,
            view_buffer,
            view_group,
            outlined: None,
        }
    }

    /// Outlines draw `draw` of `geometry` in the frames that follow (`None`: nothing): its
    /// [`feature_edges`] are built and uploaded now, once. Returns the number of edges.
    pub fn set(
        &mut self,
        gpu: &GpuContext,
        geometry: PickGeometry<'_>,
        draw: Option<u32>,
    ) -> usize {
        let Some(draw) = draw else {
            self.outlined = None;
            return 0;
        };
        let vertices = feature_edges(geometry, draw);
        let lines = (!vertices.is_empty()).then(|| Lines {
            buffer: gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("outline lines"),
                    contents: bytemuck::cast_slice(&vertices),
                    usage: wgpu::BufferUsages::VERTEX,
                }),
            vertex_count: vertices.len() as u32,
        });
        self.outlined = Some((draw, lines));
        vertices.len() / 2
    }

    /// The draw outlined.
    pub fn outlined(&self) -> Option<u32> {
        self.outlined.as_ref().map(|(draw, _)| *draw)
    }

    /// Records the outline over `colour`, tested against `depth` (the frame's, `width ×
    /// height`) from `camera`; nothing when no draw is outlined. The uniforms are written
    /// through the queue: submit before recording another outline.
    pub fn encode(
        &self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        camera: &Camera,
        (colour, depth): (&wgpu::TextureView, &DepthTarget),
        (width, height): (u32, u32),
    ) {
        let Some((_, Some(lines))) = &self.outlined else {
            return;
        };
        let uniforms = super::view_uniforms(camera, width, height, &SceneStyle::default());
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let mut pass = super::overlay_pass(encoder, "outline", colour, depth, None);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        pass.set_vertex_buffer(0, lines.buffer.slice(..));
        pass.draw(0..lines.vertex_count, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use citywalk_shaders::BuildingRecord;

    /// A box of 8 shared corners, 12 triangles, as one record.
    fn cube() -> (Vec<BuildingRecord>, Vec<SceneVertex>, Vec<u32>) {
        let vertices: Vec<SceneVertex> = (0..8u32)
            .map(|i| SceneVertex {
                position_m: [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32],
                building_id: 0,
            })
            .collect();
        let indices = vec![
            0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4,
            6, 1, 3, 5, 3, 7, 5,
        ];
        let record = BuildingRecord {
            bounds_min_m: [0.0; 3],
            first_index: 0,
            bounds_max_m: [1.0; 3],
            index_count: 36,
            base_vertex: 0,
            vertex_count: 8,
            first_part: 0,
            part_count: 0,
        };
        (vec![record], vertices, indices)
    }

    fn edges_of(records: &[BuildingRecord], vertices: &[SceneVertex], indices: &[u32]) -> usize {
        let geometry = PickGeometry {
            records,
            vertices,
            indices,
        };
        feature_edges(geometry, 0).len() / 2
    }

    #[test]
    fn a_box_has_its_twelve_edges_not_its_face_diagonals() {
        let (records, vertices, indices) = cube();
        assert_eq!(edges_of(&records, &vertices, &indices), 12);
        // The same box flat-shaded (three corners per triangle) and with mixed windings: the
        // same twelve edges.
        let mut flat = Vec::new();
        for (t, tri) in indices.chunks_exact(3).enumerate() {
            let mut corners = [tri[0], tri[1], tri[2]];
            if t % 2 == 1 {
                corners.swap(1, 2);
            }
            flat.extend(corners.map(|i| vertices[i as usize]));
        }
        let flat_indices: Vec<u32> = (0..flat.len() as u32).collect();
        let mut flat_records = records.clone();
        flat_records[0].vertex_count = flat.len() as u32;
        assert_eq!(edges_of(&flat_records, &flat, &flat_indices), 12);
        // Without its bottom (as an extruded building is): the bottom square is its boundary,
        // still twelve.
        let open: Vec<u32> = indices[6..].to_vec();
        let mut open_records = records.clone();
        open_records[0].index_count = open.len() as u32;
        assert_eq!(edges_of(&open_records, &vertices, &open), 12);
        // A draw out of range has none.
        let geometry = PickGeometry {
            records: &records,
            vertices: &vertices,
            indices: &indices,
        };
        assert!(feature_edges(geometry, 1).is_empty());
    }
}
