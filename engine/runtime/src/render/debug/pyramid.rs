//! Debug view of the hierarchical-Z pyramid: level K of an [`HzbPyramid`] drawn as a greyscale
//! full-screen image, each screen pixel showing the texel of level K that covers it
//! (`wgsl/debug_pyramid.wgsl`). A [`GreyRange`] says which distances are white and black (the
//! sky is black); the grey falls with the logarithm of the distance in between
//! ([`pyramid_grey`]). On an sRGB target the grey is decoded first (a 2.2 power), so the screen
//! shows it as computed.

use citywalk_shaders::{DEBUG_PYRAMID_WGSL, PyramidViewParams};

use crate::gpu::GpuContext;
use crate::hzb::HzbPyramid;
use crate::hzb::build::HZB_FORMAT;

/// The distances drawn white and black.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GreyRange {
    /// Near plane of the camera (m): reversed-Z depth `d` lies at distance `near_m / d`.
    pub near_m: f32,
    /// This distance and nearer is white (m).
    pub white_m: f32,
    /// This distance and farther is black (m).
    pub black_m: f32,
}

impl GreyRange {
    /// From the near plane to 5 km.
    pub fn from_near(near_m: f32) -> GreyRange {
        GreyRange {
            near_m,
            white_m: near_m,
            black_m: 5_000.0,
        }
    }

    /// The range of a scene inside the box `[min, max]` seen from `eye`: white at the nearest
    /// point of the box (the near plane inside it), black at its farthest corner, so the
    /// scene's depths use the whole grey scale.
    pub fn for_bounds(near_m: f32, eye: glam::Vec3, min: glam::Vec3, max: glam::Vec3) -> GreyRange {
        let white_m = crate::lod::distance_to_box(eye, min, max).max(near_m);
        let far = (eye - min).abs().max((eye - max).abs()).length();
        GreyRange {
            near_m,
            white_m,
            black_m: far.max(white_m * 2.0),
        }
    }
}

/// The grey level (0 black to 1 white, before any sRGB decoding) of a reversed-Z depth: 0 for
/// the sky (depth ≤ 0), else `1 − ln(distance / white) / ln(black / white)` clamped to `[0, 1]`,
/// with `distance = near_m / depth`. CPU twin of `pyramid_grey` in the shader.
pub fn pyramid_grey(depth: f32, range: &GreyRange) -> f32 {
    if depth <= 0.0 {
        return 0.0;
    }
    let distance_m = range.near_m / depth;
    let t = (distance_m / range.white_m).ln() / (range.black_m / range.white_m).ln();
    1.0 - t.clamp(0.0, 1.0)
}

/// The pyramid view's pipeline and uniforms.
#[derive(Debug)]
pub struct PyramidView {
    pipeline: wgpu::RenderPipeline,
    srgb_target: bool,
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
}

impl PyramidView {
    /// A view drawing into colour targets of `colour_format`.
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> PyramidView {
        let device = &gpu.device;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("debug pyramid"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(
                            size_of::<PyramidViewParams>() as u64
                        ),
                    },
                    count: None,
                },
                crate::render::float_texture_entry(1, wgpu::ShaderStages::FRAGMENT),
            ],
        });
        let pipeline = crate::render::fullscreen_pipeline(
            device,
            "debug pyramid",
            DEBUG_PYRAMID_WGSL,
            &layout,
            None,
            &[Some(wgpu::ColorTargetState {
                format: colour_format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        );
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("debug pyramid params"),
            size: size_of::<PyramidViewParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        PyramidView {
            pipeline,
            srgb_target: colour_format.is_srgb(),
            layout,
            params,
        }
    }

    /// Records a pass drawing level `level` of `pyramid` (clamped to its last level) over all of
    /// `target`, in the greys of `range`. Returns the level drawn. The uniforms are written
    /// through the queue: submit before recording another view.
    pub fn encode(
        &self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        pyramid: &HzbPyramid,
        level: u32,
        range: &GreyRange,
        target: &wgpu::TextureView,
    ) -> u32 {
        let level = level.min(pyramid.level_count().saturating_sub(1));
        let (level_width, level_height) = pyramid.level_size(level);
        let params = PyramidViewParams {
            level,
            level_width,
            level_height,
            srgb_target: u32::from(self.srgb_target),
            near_m: range.near_m,
            white_m: range.white_m,
            black_m: range.black_m.max(range.white_m * 1.001),
            _pad: 0.0,
        };
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        // A single-level view of mip `level`: the shader reads mip 0 of it (GPU-NOTES trap 1).
        let mip = pyramid.texture().create_view(&wgpu::TextureViewDescriptor {
            label: Some("debug pyramid level"),
            format: Some(HZB_FORMAT),
            base_mip_level: level,
            mip_level_count: Some(1),
            ..Default::default()
        });
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("debug pyramid"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(&mip),
                },
            ],
        });
        let mut pass = crate::render::begin_colour_pass(
            encoder,
            "debug pyramid",
            target,
            wgpu::LoadOp::Clear(wgpu::Color::BLACK),
            None,
        );
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.draw(0..3, 0..1);
        level
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn grey_is_white_near_black_far_away_and_for_the_sky() {
        let range = GreyRange::from_near(0.5);
        assert_eq!(pyramid_grey(1.0, &range), 1.0);
        assert_eq!(pyramid_grey(0.0, &range), 0.0);
        assert_eq!(pyramid_grey(0.5 / 10_000.0, &range), 0.0);
        // Halfway in log distance: √(0.5 · 5000) = 50 m.
        let mid = pyramid_grey(0.5 / 50.0, &range);
        assert!((mid - 0.5).abs() < 1e-5, "{mid}");
        // Nearer is brighter.
        assert!(pyramid_grey(0.5 / 10.0, &range) > pyramid_grey(0.5 / 20.0, &range));
    }

    #[test]
    fn a_scene_range_spans_the_box_seen_from_the_eye() {
        let (min, max) = (Vec3::ZERO, Vec3::new(100.0, 100.0, 30.0));
        let above = GreyRange::for_bounds(0.5, Vec3::new(50.0, 50.0, 130.0), min, max);
        assert!((above.white_m - 100.0).abs() < 1e-4);
        // The farthest corner is 148 m away: black is floored at twice the white distance.
        assert_eq!(above.black_m, 200.0);
        let far = GreyRange::for_bounds(0.5, Vec3::new(-10.0, 50.0, 2.0), min, max);
        assert!((far.white_m - 10.0).abs() < 1e-4);
        let corner = Vec3::new(110.0, 50.0, 28.0).length();
        assert!((far.black_m - corner).abs() < 1e-3, "{}", far.black_m);
        let inside = GreyRange::for_bounds(0.5, Vec3::new(10.0, 10.0, 1.7), min, max);
        assert_eq!(inside.white_m, 0.5);
        assert!(inside.black_m > 100.0);
    }
}
