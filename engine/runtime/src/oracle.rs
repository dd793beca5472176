//! The visibility oracle: the exact set of buildings with at least one visible pixel from a
//! camera, by rendering building ids into an `R32Uint` target with no culling and reading it
//! back. Every culling scheme is judged against it (a conservative culler must never drop a
//! building the oracle sees).

use citywalk_scenes::BuildingId;
use citywalk_shaders::{ID_BACKGROUND, ID_OFFSET, IDS_WGSL};

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::render::targets::{OffscreenTarget, ReadbackError};
use crate::render::view::{SceneStyle, view_uniforms};
use crate::scene_gpu::SceneGpu;

/// The id image of one view: per pixel, `building id + ID_OFFSET`, or `ID_BACKGROUND` (0) where
/// sky or ground is seen. Rows top to bottom.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct IdImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u32>,
}

impl IdImage {
    /// The building seen at pixel `(x, y)`, if any.
    pub fn building_at(&self, x: u32, y: u32) -> Option<BuildingId> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let v = self.pixels[(y * self.width + x) as usize];
        (v != ID_BACKGROUND).then(|| BuildingId(v - ID_OFFSET))
    }

    /// Pixels that show some building.
    pub fn building_pixel_count(&self) -> usize {
        self.pixels.iter().filter(|&&v| v != ID_BACKGROUND).count()
    }
}

/// The buildings visible in one view, with their pixel counts.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VisibleSet {
    /// Visible buildings, sorted by id.
    pub visible: Vec<BuildingId>,
    /// Visible pixels per building, indexed by building id (length = building count).
    pub pixel_counts: Vec<u32>,
}

impl VisibleSet {
    /// Counts the pixels of `image` per building of a scene with `building_count` buildings.
    /// Ids outside the scene (which a correct id pass never writes) are ignored and logged.
    pub fn from_id_image(image: &IdImage, building_count: usize) -> VisibleSet {
        let mut pixel_counts = vec![0u32; building_count];
        let mut stray = 0usize;
        for &v in &image.pixels {
            if v == ID_BACKGROUND {
                continue;
            }
            match pixel_counts.get_mut((v - ID_OFFSET) as usize) {
                Some(c) => *c += 1,
                None => stray += 1,
            }
        }
        if stray > 0 {
            tracing::warn!("{stray} id pixels name no building of the scene");
        }
        let visible = pixel_counts
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(i, _)| BuildingId(i as u32))
            .collect();
        VisibleSet {
            visible,
            pixel_counts,
        }
    }

    /// Whether building `id` has at least one visible pixel.
    pub fn contains(&self, id: BuildingId) -> bool {
        self.pixel_counts.get(id.index()).is_some_and(|&c| c > 0)
    }

    /// Number of visible buildings.
    pub fn len(&self) -> usize {
        self.visible.len()
    }

    /// Whether no building is visible.
    pub fn is_empty(&self) -> bool {
        self.visible.is_empty()
    }

    /// Total visible building pixels.
    pub fn total_pixels(&self) -> u64 {
        self.pixel_counts.iter().map(|&c| u64::from(c)).sum()
    }
}

/// The id pass and its readback.
#[derive(Debug)]
pub struct Oracle {
    pipeline: wgpu::RenderPipeline,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
}

impl Oracle {
    /// The id target's format.
    pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

    pub fn new(gpu: &GpuContext) -> Oracle {
        let device = &gpu.device;
        let layout = crate::render::view_bind_group_layout(device, "oracle view");
        let (view_buffer, view_group) =
            crate::render::view_buffer_and_group(device, &layout, "oracle view");
        let pipeline = crate::render::scene_pipeline(
            device,
            "oracle ids",
            IDS_WGSL,
            &layout,
            Some(Self::FORMAT),
        );
        Oracle {
            pipeline,
            view_buffer,
            view_group,
        }
    }

    /// Renders the id image of `scene` from `camera` at `width × height` and reads it back.
    pub fn id_image(
        &self,
        gpu: &GpuContext,
        scene: &SceneGpu,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<IdImage, ReadbackError> {
        let target = OffscreenTarget::new(gpu, width, height, Self::FORMAT)?;
        let uniforms = view_uniforms(camera, width, height, &SceneStyle::default());
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("oracle"),
            });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("oracle ids"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.colour_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: f64::from(ID_BACKGROUND),
                            g: 0.0,
                            b: 0.0,
                            a: 0.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(target.depth.attachment()),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.view_group, &[]);
            scene.bind(&mut pass);
            scene.draw_all(&mut pass);
        }
        gpu.queue.submit([encoder.finish()]);
        let bytes = target.read_colour(gpu)?;
        Ok(IdImage {
            width,
            height,
            pixels: bytemuck::pod_collect_to_vec(&bytes),
        })
    }

    /// The exact set of buildings with at least one visible pixel.
    pub fn visible_set(
        &self,
        gpu: &GpuContext,
        scene: &SceneGpu,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<VisibleSet, ReadbackError> {
        let image = self.id_image(gpu, scene, camera, width, height)?;
        Ok(VisibleSet::from_id_image(&image, scene.building_count()))
    }
}
