//! The GPU hierarchical-Z passes against their CPU reference (`citywalk_runtime::hzb::reference`):
//! the pyramid texel for texel, the cull box for box, and the indirect draws it appends.
//!
//! Depth buffers are written by a fullscreen pass that copies a random `R32Float` texture into
//! `frag_depth`, so the CPU knows every depth exactly; where the backend can copy depth to a
//! buffer (not GL), the depth texture is also read back and must equal the input.

use citywalk_runtime::camera::Camera;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::hzb::cull::{
    CULL_FRUSTUM_OUTSIDE, CULL_NOT_EARLY, CULL_OCCLUDED, CULL_VISIBLE, CullEntry, CullLinks,
    CullVisibility, NO_PARENT,
};
use citywalk_runtime::hzb::reference::{
    BoxProjection, DepthPyramid, HullTest, RecordCull, box_corners, erode, project_box,
    select_level,
};
use citywalk_runtime::hzb::{CullResults, HzbCull, HzbPyramid};
use citywalk_runtime::render::targets::map_read;
use citywalk_runtime::render::{float_texture_entry, fullscreen_pipeline};
use citywalk_shaders::constants::{
    CULL_R_EARLY, CULL_R_GATE_CULLED, CULL_R_KEPT, CULL_R_OCCLUDED, CULL_R_WORDS,
};
use citywalk_shaders::{BuildingRecord, CullPart, DrawIndexedIndirectArgs};
use citywalk_tests::gpu::gpu_or_skip;
use citywalk_tests::rng::Rng;
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

const DEPTH_WRITER_WGSL: &str = r"
@group(0) @binding(0) var values: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.5, 1.0);
}

@fragment
fn fs_main(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
    return textureLoad(values, vec2<i32>(p.xy), 0).r;
}
";

/// Writes `values` (row-major, `width × height`) into a new `Depth32Float` texture.
fn depth_texture(gpu: &GpuContext, width: u32, height: u32, values: &[f32]) -> wgpu::Texture {
    let device = &gpu.device;
    let size = wgpu::Extent3d {
        width,
        height,
        depth_or_array_layers: 1,
    };
    let source = device.create_texture_with_data(
        &gpu.queue,
        &wgpu::TextureDescriptor {
            label: Some("test depth values"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::R32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        },
        wgpu::util::TextureDataOrder::LayerMajor,
        bytemuck_cast(values),
    );
    let depth = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("test depth"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Depth32Float,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC,
        view_formats: &[],
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("test depth writer"),
        entries: &[float_texture_entry(0, wgpu::ShaderStages::FRAGMENT)],
    });
    let pipeline = fullscreen_pipeline(
        device,
        "test depth writer",
        DEPTH_WRITER_WGSL,
        &layout,
        Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        &[],
    );
    let source_view = source.create_view(&wgpu::TextureViewDescriptor::default());
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("test depth writer"),
        layout: &layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(&source_view),
        }],
    });
    let depth_view = depth.create_view(&wgpu::TextureViewDescriptor::default());
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("test depth writer"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(Camera::DEPTH_CLEAR),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.draw(0..3, 0..1);
    }
    gpu.queue.submit([encoder.finish()]);
    depth
}

fn bytemuck_cast(values: &[f32]) -> &[u8] {
    bytemuck::cast_slice(values)
}

/// Reads a `Depth32Float` texture back, or `None` where the backend cannot copy depth (GL).
fn read_depth(
    gpu: &GpuContext,
    depth: &wgpu::Texture,
    width: u32,
    height: u32,
) -> Option<Vec<f32>> {
    if gpu.adapter_info.backend == wgpu::Backend::Gl {
        return None;
    }
    let row = (width * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
        * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test depth readback"),
        size: u64::from(row) * u64::from(height),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: depth,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::DepthOnly,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row),
                rows_per_image: Some(height),
            },
        },
        depth.size(),
    );
    gpu.queue.submit([encoder.finish()]);
    let slice = buffer.slice(..);
    slice.map_async(wgpu::MapMode::Read, |r| r.expect("map depth readback"));
    gpu.wait_idle();
    let mapped = slice.get_mapped_range().expect("mapped depth");
    let mut out = Vec::with_capacity((width * height) as usize);
    for y in 0..height as usize {
        let start = y * row as usize;
        out.extend(
            mapped[start..start + 4 * width as usize]
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        );
    }
    Some(out)
}

/// Builds the pyramid of `values` on the GPU and reads every level back.
fn gpu_pyramid(
    gpu: &GpuContext,
    width: u32,
    height: u32,
    values: &[f32],
) -> (HzbPyramid, DepthPyramid) {
    gpu_pyramid_of(gpu, width, height, (values, None))
}

/// A depth texture holding `values`, checked by reading it back where the adapter can.
fn checked_depth_texture(
    gpu: &GpuContext,
    width: u32,
    height: u32,
    values: &[f32],
) -> wgpu::Texture {
    let depth = depth_texture(gpu, width, height, values);
    if let Some(readback) = read_depth(gpu, &depth, width, height) {
        assert!(
            readback
                .iter()
                .zip(values)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "{width}x{height}: the depth buffer does not hold the values written"
        );
    }
    depth
}

/// Builds the pyramid of `values`, or of `values` merged with `merged` (nearer kept), on the
/// GPU and reads every level back.
fn gpu_pyramid_of(
    gpu: &GpuContext,
    width: u32,
    height: u32,
    (values, merged): (&[f32], Option<&[f32]>),
) -> (HzbPyramid, DepthPyramid) {
    let depth = checked_depth_texture(gpu, width, height, values);
    let second = merged.map(|m| checked_depth_texture(gpu, width, height, m));
    let pyramid = HzbPyramid::new(gpu, width, height).expect("pyramid");
    let view = depth.create_view(&wgpu::TextureViewDescriptor::default());
    let second_view = second
        .as_ref()
        .map(|t| t.create_view(&wgpu::TextureViewDescriptor::default()));
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    match &second_view {
        Some(second_view) => pyramid.build_merged_timed(&mut encoder, &view, second_view, None),
        None => pyramid.build(&mut encoder, &view),
    }
    gpu.queue.submit([encoder.finish()]);
    let levels = pyramid.read_back(gpu).expect("pyramid readback");
    (pyramid, levels)
}

/// Random reversed-Z depths: a tenth cleared (0, the sky), the rest uniform in [0, 1).
fn random_depths(rng: &mut Rng, n: usize) -> Vec<f32> {
    (0..n)
        .map(|_| if rng.unit() < 0.1 { 0.0 } else { rng.unit() })
        .collect()
}

/// The GPU pyramid equals the CPU reference texel for texel (bit-exact) at common, odd and tiny
/// sizes, every level; so does the pyramid merged from two depth buffers, against the
/// reference of their per-texel nearer depth (the frame's depth with its occluders', these
/// eroded), and the occluder gate's pyramid of an occluder depth alone, eroded.
#[test]
fn gpu_pyramid_equals_reference_texel_for_texel() {
    let Some(gpu) = gpu_or_skip("gpu_pyramid_equals_reference_texel_for_texel") else {
        return;
    };
    let mut rng = Rng(0x4859_5a42);
    let sizes = [
        (1280, 720),
        (1366, 768),
        (1001, 777),
        (640, 480),
        (1, 1),
        (3, 5),
        (17, 9),
        (2, 1),
        (1, 7),
        (33, 65),
    ];
    for (w, h) in sizes {
        let values = random_depths(&mut rng, (w * h) as usize);
        let (pyramid, gpu_levels) = gpu_pyramid(&gpu, w, h, &values);
        let cpu = DepthPyramid::build(w, h, &values);
        assert_eq!(pyramid.level_count() as usize, cpu.levels.len(), "{w}x{h}");
        assert_levels_equal(&format!("{w}x{h}"), &gpu_levels, &cpu);

        let occluders = random_depths(&mut rng, (w * h) as usize);
        let (_, merged_levels) = gpu_pyramid_of(&gpu, w, h, (&values, Some(&occluders)));
        let eroded = erode(w, h, &occluders);
        let nearer: Vec<f32> = values.iter().zip(&eroded).map(|(a, b)| a.max(*b)).collect();
        let cpu_merged = DepthPyramid::build(w, h, &nearer);
        assert_levels_equal(&format!("{w}x{h} merged"), &merged_levels, &cpu_merged);

        // The occluder gate's pyramid: the occluders' depth alone, eroded.
        let depth = checked_depth_texture(&gpu, w, h, &occluders);
        let pyramid = HzbPyramid::new(&gpu, w, h).expect("pyramid");
        let view = depth.create_view(&wgpu::TextureViewDescriptor::default());
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        pyramid.build_occluders_timed(&mut encoder, &view, None);
        gpu.queue.submit([encoder.finish()]);
        let gate_levels = pyramid.read_back(&gpu).expect("pyramid readback");
        let cpu_gate = DepthPyramid::build(w, h, &eroded);
        assert_levels_equal(&format!("{w}x{h} eroded"), &gate_levels, &cpu_gate);
    }
}

/// Every level of `gpu` equals `cpu`'s in size and bit for bit.
fn assert_levels_equal(what: &str, gpu: &DepthPyramid, cpu: &DepthPyramid) {
    assert_eq!(gpu.levels.len(), cpu.levels.len(), "{what}");
    for (l, (g, c)) in gpu.levels.iter().zip(&cpu.levels).enumerate() {
        assert_eq!(
            (g.width, g.height),
            (c.width, c.height),
            "{what} level {l} size"
        );
        if let Some(i) = (0..c.depth.len()).find(|&i| g.depth[i].to_bits() != c.depth[i].to_bits())
        {
            panic!(
                "{what} level {l}: texel ({}, {}) GPU {} CPU {}",
                i as u32 % c.width,
                i as u32 / c.width,
                g.depth[i],
                c.depth[i]
            );
        }
    }
}

/// A depth buffer seen from a camera: sky (0) above, random walls (screen rectangles reaching
/// the bottom edge) at 8–80 m.
fn walls_depth(rng: &mut Rng, camera: &Camera, width: u32, height: u32) -> Vec<f32> {
    let mut depth = vec![0.0f32; (width * height) as usize];
    for _ in 0..25 {
        let w = (rng.range(0.05, 0.4) * width as f32) as u32;
        let x0 = (rng.unit() * width as f32) as u32;
        let y0 = (rng.range(0.2, 0.8) * height as f32) as u32;
        let d = camera.near_m / rng.range(8.0, 80.0);
        for y in y0..height {
            for x in x0..(x0 + w).min(width) {
                let t = &mut depth[(y * width + x) as usize];
                *t = t.max(d);
            }
        }
    }
    depth
}

/// Random boxes around a camera: most in front (1–250 m), and some crossing the near plane,
/// behind the camera, on the frustum's edges, and huge ones covering the whole screen.
fn random_boxes(rng: &mut Rng, camera: &Camera, aspect: f32, n: usize) -> Vec<(Vec3, Vec3)> {
    let forward = camera.forward();
    let right = camera.right();
    let up = right.cross(forward);
    let t = (camera.fov_y_rad * 0.5).tan();
    let along = |ndc_x: f32, ndc_y: f32, d: f32| {
        camera.position + d * (forward + ndc_x * t * aspect * right + ndc_y * t * up)
    };
    (0..n)
        .map(|i| {
            let (centre, half) = match i % 10 {
                0..=5 => (
                    along(
                        rng.range(-1.6, 1.6),
                        rng.range(-1.6, 1.6),
                        rng.range(1.0, 250.0),
                    ),
                    Vec3::new(
                        rng.range(0.1, 15.0),
                        rng.range(0.1, 15.0),
                        rng.range(0.1, 15.0),
                    ),
                ),
                6 => (
                    camera.position
                        + Vec3::new(
                            rng.range(-1.0, 1.0),
                            rng.range(-1.0, 1.0),
                            rng.range(-1.0, 1.0),
                        ),
                    Vec3::splat(rng.range(0.05, 2.0)),
                ),
                7 => (
                    camera.position - forward * rng.range(2.0, 100.0)
                        + Vec3::new(
                            rng.range(-20.0, 20.0),
                            rng.range(-20.0, 20.0),
                            rng.range(-5.0, 5.0),
                        ),
                    Vec3::splat(rng.range(0.2, 10.0)),
                ),
                8 => {
                    // On a random edge of the frustum, a little inside or outside.
                    let s = if rng.unit() < 0.5 { -1.0 } else { 1.0 };
                    let edge = s * rng.range(0.97, 1.03);
                    let other = rng.range(-1.0, 1.0);
                    let (x, y) = if rng.unit() < 0.5 {
                        (edge, other)
                    } else {
                        (other, edge)
                    };
                    (
                        along(x, y, rng.range(2.0, 200.0)),
                        Vec3::splat(rng.range(0.02, 3.0)),
                    )
                }
                _ => (
                    along(
                        rng.range(-0.3, 0.3),
                        rng.range(-0.3, 0.3),
                        rng.range(30.0, 120.0),
                    ),
                    Vec3::splat(rng.range(25.0, 400.0)),
                ),
            };
            (centre - half, centre + half)
        })
        .collect()
}

/// Status of one record by the CPU reference (its box, then its parts).
fn cpu_status(
    pyramid: &DepthPyramid,
    vp: Mat4,
    record: &BuildingRecord,
    parts: &[CullPart],
) -> u32 {
    match pyramid.cull_record(vp, record, parts) {
        RecordCull::Outside => CULL_FRUSTUM_OUTSIDE,
        RecordCull::Occluded => CULL_OCCLUDED,
        RecordCull::Visible => CULL_VISIBLE,
    }
}

/// A prism over the plan quadrilateral `xy` (counter-clockwise) from `z0` to `z1`.
fn prism(xy: [(f32, f32); 4], z0: f32, z1: f32) -> CullPart {
    CullPart {
        corners_xy: [
            [xy[0].0, xy[0].1, xy[1].0, xy[1].1],
            [xy[2].0, xy[2].1, xy[3].0, xy[3].1],
        ],
        z_min_m: z0,
        z_max_m: z1,
        _pad0: 0,
        _pad1: 0,
    }
}

/// Parts inside each box, as a building's are inside its box: none for every third box, a
/// diamond (the box's plan rotated by 45° and inscribed) for the next, and a low diamond with a
/// square tower in the middle for the last.
fn parts_for(boxes: &[(Vec3, Vec3)]) -> (Vec<CullPart>, Vec<(u32, u32)>) {
    let mut parts = Vec::new();
    let mut ranges = Vec::new();
    for (i, (lo, hi)) in boxes.iter().enumerate() {
        let first = parts.len() as u32;
        let c = (*lo + *hi) * 0.5;
        let diamond = [(c.x, lo.y), (hi.x, c.y), (c.x, hi.y), (lo.x, c.y)];
        match i % 3 {
            1 => parts.push(prism(diamond, lo.z, hi.z)),
            2 => {
                parts.push(prism(diamond, lo.z, lo.z + 0.4 * (hi.z - lo.z)));
                let q = (*hi - *lo) * 0.125;
                let tower = [
                    (c.x - q.x, c.y - q.y),
                    (c.x + q.x, c.y - q.y),
                    (c.x + q.x, c.y + q.y),
                    (c.x - q.x, c.y + q.y),
                ];
                parts.push(prism(tower, lo.z, hi.z));
            }
            _ => {}
        }
        ranges.push((first, parts.len() as u32 - first));
    }
    (parts, ranges)
}

/// Records with unique draw ranges, so that each command names its box, and the parts of
/// [`parts_for`].
fn records_for(boxes: &[(Vec3, Vec3)]) -> (Vec<BuildingRecord>, Vec<CullPart>) {
    let (parts, ranges) = parts_for(boxes);
    let records = boxes
        .iter()
        .zip(ranges)
        .enumerate()
        .map(|(i, ((lo, hi), (first_part, part_count)))| BuildingRecord {
            bounds_min_m: lo.to_array(),
            first_index: i as u32 * 7,
            bounds_max_m: hi.to_array(),
            index_count: 3 * (i as u32 % 50 + 1),
            base_vertex: i as i32 * 3 - 1000,
            vertex_count: 4,
            first_part,
            part_count,
        })
        .collect();
    (records, parts)
}

/// Uploads `records`, culls them against `pyramid` seen through `vp` and reads the results back.
fn cull_records(
    gpu: &GpuContext,
    cull: &mut HzbCull,
    (records, parts): (&[BuildingRecord], &[CullPart]),
    pyramid: &HzbPyramid,
    vp: Mat4,
) -> CullResults {
    let records_buffer = gpu
        .device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("test records"),
            contents: bytemuck::cast_slice(records),
            usage: wgpu::BufferUsages::STORAGE,
        });
    let parts_buffer = (!parts.is_empty()).then(|| {
        gpu.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("test parts"),
                contents: bytemuck::cast_slice(parts),
                usage: wgpu::BufferUsages::STORAGE,
            })
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    cull.encode(
        gpu,
        &mut encoder,
        (&records_buffer, parts_buffer.as_ref()),
        records.len() as u32,
        pyramid,
        vp,
    )
    .expect("cull");
    gpu.queue.submit([encoder.finish()]);
    cull.read_back(gpu, records.len() as u32)
        .expect("cull readback")
}

fn key(c: &DrawIndexedIndirectArgs) -> (u32, u32, i32, u32, u32) {
    (
        c.first_index,
        c.index_count,
        c.base_vertex,
        c.instance_count,
        c.first_instance,
    )
}

/// The GPU cull against `project_box` + `is_occluded` on the CPU with the same matrices and the
/// same pyramid, for thousands of boxes from three cameras at two viewport sizes.
///
/// Rule asserted: the GPU is never less conservative — where it says occluded the CPU says
/// occluded, where it says frustum-outside the CPU says outside (zero exceptions) — and the two
/// agree on at least 99.9 % of boxes (the GPU widens its comparisons by a rounding bound, so it
/// may keep a few boxes the CPU culls, never the reverse). The indirect commands are exactly the
/// draws of the boxes the GPU reports visible.
#[test]
fn gpu_cull_matches_reference_and_never_culls_more() {
    let Some(gpu) = gpu_or_skip("gpu_cull_matches_reference_and_never_culls_more") else {
        return;
    };
    let mut rng = Rng(0x0c11_0000);
    let cameras = [
        Camera::new(Vec3::new(0.0, 0.0, 1.7), 0.3, 0.05),
        Camera::new(Vec3::new(120.0, -40.0, 35.0), 2.2, -0.35),
        Camera::new(Vec3::new(-500.0, 800.0, 3.0), -1.2, 0.2),
    ];
    let mut cull = HzbCull::new(&gpu, 1024);
    let (mut total, mut agree) = (0usize, 0usize);
    let mut cpu_counts = [0usize; 3];
    // Boxes a 2x2 test at the coarse level alone would keep and the fine test culls, and how
    // many of them the GPU culls too.
    let (mut fine_only, mut fine_only_gpu) = (0usize, 0usize);
    // Records whose box the test keeps and whose parts it culls, and how many of them the GPU
    // culls too.
    let (mut parts_only, mut parts_only_gpu) = (0usize, 0usize);
    for (c, camera) in cameras.iter().enumerate() {
        let (w, h) = if c == 1 { (1001, 777) } else { (1280, 720) };
        let depth = walls_depth(&mut rng, camera, w, h);
        let (pyramid, gpu_levels) = gpu_pyramid(&gpu, w, h, &depth);
        let cpu_pyramid = DepthPyramid::build(w, h, &depth);
        assert!(
            gpu_levels == cpu_pyramid,
            "camera {c}: GPU pyramid differs from the reference"
        );
        let vp = camera.view_proj(w as f32 / h as f32);
        let boxes = random_boxes(&mut rng, camera, w as f32 / h as f32, 4000);
        let (records, parts) = records_for(&boxes);
        let results = cull_records(&gpu, &mut cull, (&records, &parts), &pyramid, vp);
        assert_eq!(results.status.len(), boxes.len());
        for (i, ((lo, hi), &g)) in boxes.iter().zip(&results.status).enumerate() {
            let cpu = cpu_status(&cpu_pyramid, vp, &records[i], &parts);
            cpu_counts[cpu as usize] += 1;
            assert!(
                g == cpu || g == CULL_VISIBLE,
                "camera {c} box {i} [{lo}, {hi}]: GPU status {g}, CPU status {cpu} ({:?})",
                project_box(vp, *lo, *hi, w, h)
            );
            total += 1;
            agree += usize::from(g == cpu);
            if let BoxProjection::Rect {
                rect,
                nearest_depth,
            } = project_box(vp, *lo, *hi, w, h)
                && cpu_pyramid.is_occluded(rect, nearest_depth)
                && nearest_depth >= cpu_pyramid.farthest_in(rect, select_level(rect))
            {
                fine_only += 1;
                fine_only_gpu += usize::from(g == CULL_OCCLUDED);
            }
            let box_test = cpu_pyramid.test_hull(vp, &box_corners(*lo, *hi));
            if cpu != CULL_VISIBLE && matches!(box_test, HullTest::Kept | HullTest::CrossesNear) {
                parts_only += 1;
                parts_only_gpu += usize::from(g == cpu);
            }
        }
        // The commands are exactly the GPU-visible boxes' draws.
        let mut expected: Vec<_> = records
            .iter()
            .zip(&results.status)
            .filter(|(_, s)| **s == CULL_VISIBLE)
            .map(|(r, _)| key(&r.draw_args()))
            .collect();
        let mut written: Vec<_> = results.commands.iter().map(key).collect();
        expected.sort_unstable();
        written.sort_unstable();
        assert_eq!(written, expected, "camera {c}: indirect commands");
    }
    eprintln!(
        "{agree} of {total} boxes agree; CPU: {} visible, {} outside, {} occluded \
         ({fine_only} only by the fine level, {fine_only_gpu} of them culled by the GPU; \
         {parts_only} only by their parts, {parts_only_gpu} of them culled by the GPU)",
        cpu_counts[0], cpu_counts[1], cpu_counts[2]
    );
    // The parts are exercised, and the GPU culls what they hide.
    assert!(parts_only * 50 > total, "only {parts_only} culls by parts");
    assert!(
        parts_only_gpu as f64 >= 0.99 * parts_only as f64,
        "the GPU culls only {parts_only_gpu} of the {parts_only} records only their parts hide"
    );
    // The fine level is exercised, and the GPU really reads it (not only the coarse texels).
    assert!(fine_only * 100 > total, "only {fine_only} fine-level culls");
    assert!(
        fine_only_gpu as f64 >= 0.99 * fine_only as f64,
        "the GPU culls only {fine_only_gpu} of the {fine_only} boxes only the fine level hides"
    );
    // Every outcome is exercised.
    for (s, n) in cpu_counts.iter().enumerate() {
        assert!(*n * 20 > total, "status {s} only {n} times of {total}");
    }
    assert!(
        agree as f64 >= 0.999 * total as f64,
        "only {agree} of {total} boxes agree"
    );
}

fn storage_buffer(gpu: &GpuContext, label: &str, contents: &[u8]) -> wgpu::Buffer {
    gpu.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        })
}

/// Reads a storage buffer's `u32` words back (the buffer needs `COPY_SRC`).
fn read_words(gpu: &GpuContext, buffer: &wgpu::Buffer) -> Vec<u32> {
    let read = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("words readback"),
        size: buffer.size(),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &read, 0, buffer.size());
    gpu.queue.submit([encoder.finish()]);
    bytemuck::pod_collect_to_vec(&map_read(gpu, &read).expect("words"))
}

/// The reports of one frame's early entry (`early_words`) and main cull (`cull_words`) say what
/// their statuses say: the early list holds the boxes the early entry drew, the kept list those
/// the cull found visible (each once, in any order), the counts the occluded and the gate-culled
/// boxes.
fn check_report(
    early_words: &[u32],
    cull_words: &[u32],
    (early_status, status): (&[u32], &[u32]),
    what: &str,
) {
    let list = |words: &[u32], length_word: u32, first: usize| -> Vec<u32> {
        let capacity = (words.len() - CULL_R_WORDS as usize) / 2;
        let length = words[length_word as usize] as usize;
        assert!(
            length <= capacity,
            "{what}: list of {length} past {capacity}"
        );
        let mut ids = words[first..first + length].to_vec();
        ids.sort_unstable();
        ids
    };
    let visible = |statuses: &[u32]| -> Vec<u32> {
        (0..statuses.len() as u32)
            .filter(|&j| statuses[j as usize] == CULL_VISIBLE)
            .collect()
    };
    let early_first = CULL_R_WORDS as usize + (early_words.len() - CULL_R_WORDS as usize) / 2;
    assert_eq!(
        list(early_words, CULL_R_EARLY, early_first),
        visible(early_status),
        "{what}: early list"
    );
    assert_eq!(
        list(cull_words, CULL_R_KEPT, CULL_R_WORDS as usize),
        visible(status),
        "{what}: kept list"
    );
    let count = |statuses: &[u32], f: &dyn Fn(u32) -> bool| {
        statuses.iter().filter(|&&s| f(s)).count() as u32
    };
    assert_eq!(
        cull_words[CULL_R_OCCLUDED as usize],
        count(status, &|s| s == CULL_OCCLUDED),
        "{what}: occluded"
    );
    assert_eq!(
        early_words[CULL_R_GATE_CULLED as usize],
        count(early_status, &|s| s != CULL_VISIBLE && s != CULL_NOT_EARLY),
        "{what}: gate-culled"
    );
    assert_eq!(
        early_words[CULL_R_KEPT as usize], 0,
        "{what}: the early entry keeps none"
    );
    assert_eq!(
        cull_words[CULL_R_EARLY as usize], 0,
        "{what}: the cull draws none early"
    );
}

/// The early entry points and the GPU-resident visibility (`engine::frame`): box `j` stands for
/// draw id `7·j mod n` (records read by draw id), the stamps say which draw ids the last frame
/// kept (stamp 9 of frame 10; stale stamps 8 and 0 do not count), and a cluster draw id above
/// every fifth building carries stamp 9 too (its buildings count as visible). `gate` takes
/// exactly the visible-last-frame boxes inside the frustum and gives each the plain cull's status
/// (which follows the CPU reference with the usual rule), drawing and marking the visible ones;
/// `early` (frustum only) draws and marks every box it takes; the main cull, reading the marks,
/// writes the plain status, appends the draws of the visible unmarked boxes only, and stamps
/// every visible draw id with 10, leaving the others and the cluster as they were; the two
/// passes' reports list and count what their statuses say ([`check_report`]). Two cameras,
/// 1280 × 720 and 1001 × 777.
#[test]
fn early_entries_read_the_stamps_and_the_cull_marks_them() {
    let Some(gpu) = gpu_or_skip("early_entries_read_the_stamps_and_the_cull_marks_them") else {
        return;
    };
    let mut rng = Rng(0x0c11_6a7e);
    let cameras = [
        Camera::new(Vec3::new(0.0, 0.0, 1.7), 0.3, 0.05),
        Camera::new(Vec3::new(120.0, -40.0, 35.0), 2.2, -0.35),
    ];
    let (mut plain, mut early, mut main) = (
        HzbCull::new(&gpu, 64),
        HzbCull::new(&gpu, 64),
        HzbCull::new(&gpu, 64),
    );
    let storage = |label, contents: &[u8]| storage_buffer(&gpu, label, contents);
    let (mut marked_total, mut kept_out_total, mut cpu_agree, mut taken_total) = (0, 0, 0, 0);
    for (c, camera) in cameras.iter().enumerate() {
        let (w, h) = if c == 1 { (1001, 777) } else { (1280, 720) };
        let depth = walls_depth(&mut rng, camera, w, h);
        let (pyramid, _) = gpu_pyramid(&gpu, w, h, &depth);
        let cpu_pyramid = DepthPyramid::build(w, h, &depth);
        let vp = camera.view_proj(w as f32 / h as f32);
        let boxes = random_boxes(&mut rng, camera, w as f32 / h as f32, 3000);
        // Records by draw id; draw id n is the cluster (no record of its own is culled).
        let (records, parts) = records_for(&boxes);
        let n = records.len() as u32;
        let reference = cull_records(&gpu, &mut plain, (&records, &parts), &pyramid, vp);
        let ids: Vec<u32> = (0..n).map(|j| (7 * j) % n).collect();
        let cluster = n;
        let mut parents = vec![NO_PARENT; n as usize + 1];
        let mut stamps = vec![0u32; n as usize + 1];
        for d in 0..n {
            if d % 5 == 1 {
                parents[d as usize] = cluster;
            }
            stamps[d as usize] = match d % 3 {
                0 => 9,
                1 => 8,
                _ => 0,
            };
        }
        stamps[cluster as usize] = 9;
        let visible_last = |d: u32| d.is_multiple_of(3) || d % 5 == 1;
        let records_buffer = storage("records", bytemuck::cast_slice(&records));
        let parts_buffer = storage("parts", bytemuck::cast_slice(&parts));
        let ids_buffer = storage("draw ids", bytemuck::cast_slice(&ids));
        let parents_buffer = storage("parents", bytemuck::cast_slice(&parents));
        for entry in [CullEntry::Gate, CullEntry::Early] {
            let stamps_buffer = storage("stamps", bytemuck::cast_slice(&stamps));
            // Flags start at 1 for every box: the caller clears them.
            let flags = storage("flags", &vec![1u8; records.len() * 4]);
            let links = CullLinks {
                draw_ids: Some(&ids_buffer),
                drawn_early: Some(&flags),
                visibility: Some(CullVisibility {
                    stamps: &stamps_buffer,
                    parents: &parents_buffer,
                    frame_stamp: 10,
                    building_count: n,
                }),
            };
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
            encoder.clear_buffer(&flags, 0, None);
            early.clear_report(&mut encoder);
            main.clear_report(&mut encoder);
            for (cull, e) in [(&mut early, entry), (&mut main, CullEntry::Cull)] {
                cull.encode_entry(
                    &gpu,
                    &mut encoder,
                    (e, &records_buffer, Some(&parts_buffer), links),
                    n,
                    (&pyramid, vp),
                    None,
                )
                .expect("cull");
            }
            gpu.queue.submit([encoder.finish()]);
            let taken = early.read_back(&gpu, n).expect("early readback");
            let culled = main.read_back(&gpu, n).expect("cull readback");
            let marked: Vec<bool> = read_words(&gpu, &flags).iter().map(|&f| f != 0).collect();
            let after = read_words(&gpu, &stamps_buffer);
            check_report(
                &read_words(&gpu, early.report_buffer()),
                &read_words(&gpu, main.report_buffer()),
                (&taken.status, &culled.status),
                &format!("camera {c} {entry:?}"),
            );
            let mut expected_early = Vec::new();
            for j in 0..n as usize {
                let d = ids[j];
                let plain_status = reference.status[d as usize];
                let t = taken.status[j];
                if !visible_last(d) {
                    assert_eq!(t, CULL_NOT_EARLY, "camera {c} {entry:?}: box {j} (id {d})");
                } else if plain_status != CULL_FRUSTUM_OUTSIDE {
                    // Its box is in the frustum: taken.
                    let want = if entry == CullEntry::Gate {
                        plain_status
                    } else {
                        CULL_VISIBLE
                    };
                    assert_eq!(t, want, "camera {c} {entry:?}: box {j} (id {d})");
                } else {
                    // Outside by its box (not taken) or by its parts alone (the gate: outside).
                    assert!(
                        t == CULL_NOT_EARLY || t == CULL_FRUSTUM_OUTSIDE || t == CULL_VISIBLE,
                        "camera {c} {entry:?}: box {j} (id {d}): {t}"
                    );
                }
                if entry == CullEntry::Gate && t != CULL_NOT_EARLY {
                    let cpu = cpu_status(&cpu_pyramid, vp, &records[d as usize], &parts);
                    assert!(
                        t == cpu || t == CULL_VISIBLE,
                        "camera {c}: gate box {j}: GPU status {t}, CPU status {cpu}"
                    );
                    cpu_agree += usize::from(t == cpu);
                    taken_total += 1;
                    kept_out_total += usize::from(t != CULL_VISIBLE);
                }
                assert_eq!(
                    marked[j],
                    t == CULL_VISIBLE,
                    "camera {c} {entry:?}: mark {j}"
                );
                if t == CULL_VISIBLE {
                    expected_early.push(key(&records[d as usize].draw_args()));
                }
                // The main cull: the plain status; the stamp of a visible draw id is this
                // frame's, the others keep theirs.
                assert_eq!(
                    culled.status[j], plain_status,
                    "camera {c}: main cull box {j}"
                );
                let stamp = if plain_status == CULL_VISIBLE {
                    10
                } else {
                    stamps[d as usize]
                };
                assert_eq!(after[d as usize], stamp, "camera {c}: stamp of draw id {d}");
            }
            assert_eq!(after[cluster as usize], 9, "the cluster was no candidate");
            let mut written: Vec<_> = taken.commands.iter().map(key).collect();
            expected_early.sort_unstable();
            written.sort_unstable();
            assert_eq!(
                written, expected_early,
                "camera {c} {entry:?}: early commands"
            );
            let mut expected: Vec<_> = (0..n as usize)
                .filter(|&j| culled.status[j] == CULL_VISIBLE && !marked[j])
                .map(|j| key(&records[ids[j] as usize].draw_args()))
                .collect();
            let mut written: Vec<_> = culled.commands.iter().map(key).collect();
            expected.sort_unstable();
            written.sort_unstable();
            assert_eq!(written, expected, "camera {c}: the main cull's commands");
            marked_total += marked.iter().filter(|&&m| m).count();
        }
    }
    eprintln!(
        "early entries: {marked_total} boxes marked, the gate kept {kept_out_total} out, \
         {cpu_agree} of {taken_total} as the CPU reference"
    );
    assert!(
        cpu_agree as f64 >= 0.999 * taken_total as f64,
        "the gate agrees with the CPU reference on only {cpu_agree} of {taken_total} boxes"
    );
    // Both outcomes of the gate are exercised.
    assert!(
        marked_total > 50 && kept_out_total > 50,
        "{marked_total} marked, {kept_out_total} kept out"
    );
}

/// Buildings beside and behind a pedestrian: boxes that cross the eye plane. Those wholly
/// beyond a side of the view are frustum-culled by the CPU reference and the GPU alike (they
/// used to be kept as "unbounded"); those partly in view are kept by both; the GPU follows the
/// reference with the usual rule (never culls what it keeps). Viewport 1366 × 768.
#[test]
fn gpu_culls_boxes_crossing_the_eye_plane_outside_the_view() {
    let Some(gpu) = gpu_or_skip("gpu_culls_boxes_crossing_the_eye_plane_outside_the_view") else {
        return;
    };
    let mut rng = Rng(0x00e7_e001);
    let (w, h) = (1366, 768);
    let camera = Camera::new(Vec3::new(3.0, -2.0, 1.7), 0.7, 0.1);
    let forward = camera.forward();
    let right = camera.right();
    // A near wall straight ahead on the right half of the screen, sky elsewhere.
    let depth: Vec<f32> = (0..w * h)
        .map(|i| {
            if i % w > w / 2 {
                camera.near_m / 6.0
            } else {
                0.0
            }
        })
        .collect();
    let (pyramid, _) = gpu_pyramid(&gpu, w, h, &depth);
    let cpu_pyramid = DepthPyramid::build(w, h, &depth);
    let vp = camera.view_proj(w as f32 / h as f32);
    // Boxes from 1-30 m behind the eye to 1-30 m ahead, 1-60 m to either side.
    let boxes: Vec<(Vec3, Vec3)> = (0..3000)
        .map(|_| {
            let side = if rng.unit() < 0.5 { -1.0 } else { 1.0 };
            let a = camera.position - forward * rng.range(1.0, 30.0)
                + right * side * rng.range(1.0, 60.0);
            let b = camera.position
                + forward * rng.range(1.0, 30.0)
                + right * side * rng.range(1.0, 60.0);
            let z = Vec3::new(0.0, 0.0, rng.range(3.0, 80.0));
            let lo = a.min(b) - Vec3::new(0.0, 0.0, a.z);
            (lo, a.max(b) + z)
        })
        .collect();
    let (records, parts) = records_for(&boxes);
    let mut cull = HzbCull::new(&gpu, 64);
    let results = cull_records(&gpu, &mut cull, (&records, &parts), &pyramid, vp);
    let (mut crossing, mut outside, mut outside_gpu, mut kept) = (0, 0, 0, 0);
    for (i, ((lo, hi), &g)) in boxes.iter().zip(&results.status).enumerate() {
        let projection = project_box(vp, *lo, *hi, w, h);
        let cpu = cpu_status(&cpu_pyramid, vp, &records[i], &parts);
        assert!(
            g == cpu || g == CULL_VISIBLE,
            "box {i} [{lo}, {hi}]: GPU {g}, CPU {cpu} ({projection:?})"
        );
        // Crossing the eye plane: some corner behind the eye, some in front.
        let depths: Vec<f32> = (0..8)
            .map(|k| {
                let corner = Vec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                );
                (corner - camera.position).dot(forward)
            })
            .collect();
        if depths.iter().any(|&d| d < 0.0) && depths.iter().any(|&d| d > 1.0) {
            crossing += 1;
            match projection {
                BoxProjection::Outside => {
                    outside += 1;
                    outside_gpu += usize::from(g == CULL_FRUSTUM_OUTSIDE);
                }
                BoxProjection::CrossesNear => kept += 1,
                BoxProjection::Rect { .. } => {}
            }
        }
    }
    eprintln!(
        "{crossing} boxes cross the eye plane: {outside} outside the view ({outside_gpu} culled \
         by the GPU), {kept} kept"
    );
    assert!(crossing > 2000, "only {crossing} crossing boxes");
    assert!(
        outside > 200 && kept > 200,
        "{outside} outside, {kept} kept"
    );
    assert!(
        outside_gpu as f64 >= 0.99 * outside as f64,
        "the GPU culls {outside_gpu} of {outside}"
    );
}

/// Wall-clock timings (submit + wait) on this adapter: pyramid build at 1280×720 and culls of
/// 10k and 100k boxes. Run with `cargo test --release -p citywalk-tests --test hzb_gpu --
/// --ignored --nocapture`.
#[test]
#[ignore = "timing, run by hand"]
fn hzb_gpu_timings() {
    let Some(gpu) = gpu_or_skip("hzb_gpu_timings") else {
        return;
    };
    let mut rng = Rng(7);
    let camera = Camera::new(Vec3::new(0.0, 0.0, 1.7), 0.3, 0.05);
    let (w, h) = (1280, 720);
    let depth_values = walls_depth(&mut rng, &camera, w, h);
    let depth = depth_texture(&gpu, w, h, &depth_values);
    let view = depth.create_view(&wgpu::TextureViewDescriptor::default());
    let pyramid = HzbPyramid::new(&gpu, w, h).expect("pyramid");
    let time = |f: &dyn Fn(&mut wgpu::CommandEncoder)| {
        let mut samples = Vec::new();
        for i in 0..25 {
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
            f(&mut encoder);
            let start = std::time::Instant::now();
            gpu.queue.submit([encoder.finish()]);
            gpu.wait_idle();
            if i >= 5 {
                samples.push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
        samples.sort_by(f64::total_cmp);
        (samples[samples.len() / 2], samples[0])
    };
    let (median, best) = time(&|e| pyramid.build(e, &view));
    eprintln!(
        "{}: pyramid build {w}x{h} ({} levels): median {median:.2} ms, best {best:.2} ms",
        gpu.adapter_summary(),
        pyramid.level_count()
    );
    let vp = camera.view_proj(w as f32 / h as f32);
    for n in [10_000usize, 100_000] {
        let boxes = random_boxes(&mut rng, &camera, w as f32 / h as f32, n);
        let (records, parts) = records_for(&boxes);
        let parts_buffer = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("timing parts"),
                contents: bytemuck::cast_slice(&parts),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let records_buffer = gpu
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("timing records"),
                contents: bytemuck::cast_slice(&records),
                usage: wgpu::BufferUsages::STORAGE,
            });
        let cull = std::cell::RefCell::new(HzbCull::new(&gpu, n as u32));
        let (median, best) = time(&|e| {
            cull.borrow_mut()
                .encode(
                    &gpu,
                    e,
                    (&records_buffer, Some(&parts_buffer)),
                    n as u32,
                    &pyramid,
                    vp,
                )
                .expect("cull");
        });
        eprintln!("cull {n} boxes: median {median:.2} ms, best {best:.2} ms");
    }
}

/// The frame-script path on a real scene: depth from the brute renderer, the pyramid built from
/// that depth target, the cull of the scene's own building records. The GPU statuses follow the
/// CPU reference with the rule above, and no building that the id-buffer oracle sees (at least
/// one pixel) is culled.
#[test]
fn gpu_cull_of_a_rendered_city_never_hides_a_visible_building() {
    let Some(gpu) = gpu_or_skip("gpu_cull_of_a_rendered_city_never_hides_a_visible_building")
    else {
        return;
    };
    use citywalk_runtime::oracle::Oracle;
    use citywalk_runtime::render::{BruteRenderer, OffscreenTarget};
    use citywalk_runtime::scene_gpu::SceneGpu;

    let mut rng = Rng(0x5eed_c17e);
    // A 20 × 20 grid of blocks 25 m apart, buildings 10–20 m wide and 4–60 m tall: streets at
    // least 5 m wide.
    let mut specs = Vec::new();
    for gy in 0..20 {
        for gx in 0..20 {
            let (x0, y0) = (f64::from(gx) * 25.0, f64::from(gy) * 25.0);
            let (w, d) = (rng.range(10.0, 20.0), rng.range(10.0, 20.0));
            specs.push((
                x0,
                y0,
                x0 + f64::from(w),
                y0 + f64::from(d),
                rng.range(4.0, 60.0),
            ));
        }
    }
    let city = citywalk_tests::city_builder::boxes(&specs);
    let scene = SceneGpu::upload_city(&gpu, &city).expect("the scene fits the GPU");
    let n = scene.building_count() as u32;
    let renderer = BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
    let oracle = Oracle::new(&gpu);
    let (w, h) = (640, 360);
    let target = OffscreenTarget::new(&gpu, w, h, BruteRenderer::PNG_FORMAT).expect("target");
    let pyramid = HzbPyramid::new(&gpu, w, h).expect("pyramid");
    let mut cull = HzbCull::new(&gpu, n);
    let (mut occluded, mut total, mut agree) = (0usize, 0usize, 0usize);
    for k in 0..6 {
        // In a street (x = 22.5 + 25 i), pedestrian height, random heading.
        let position = Vec3::new(
            22.5 + 25.0 * (k * 3 % 19) as f32,
            rng.range(0.0, 480.0),
            rng.range(1.5, 12.0),
        );
        let camera = Camera::new(
            position,
            rng.range(0.0, std::f32::consts::TAU),
            rng.range(-0.2, 0.2),
        );
        let vp = camera.view_proj(w as f32 / h as f32);
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        renderer.encode(
            &gpu,
            &mut encoder,
            &scene,
            &camera,
            &target.colour_view,
            &target.depth,
        );
        pyramid.build(&mut encoder, &target.depth.view);
        cull.encode(
            &gpu,
            &mut encoder,
            (
                &scene.all.as_ref().expect("a plain scene").records_buffer,
                Some(&scene.parts_buffer),
            ),
            n,
            &pyramid,
            vp,
        )
        .expect("cull");
        gpu.queue.submit([encoder.finish()]);
        let results = cull.read_back(&gpu, n).expect("cull readback");
        let gpu_levels = pyramid.read_back(&gpu).expect("pyramid readback");
        let level0 = &gpu_levels.levels[0];
        let cpu_pyramid = DepthPyramid::build(w, h, &level0.depth);
        assert!(
            gpu_levels == cpu_pyramid,
            "camera {k}: pyramid differs from the reference"
        );
        let seen = oracle
            .visible_set(&gpu, &scene, &camera, w, h)
            .expect("oracle");
        assert!(!seen.is_empty(), "camera {k} sees no building");
        for (i, r) in scene.records.iter().enumerate() {
            let cpu = cpu_status(&cpu_pyramid, vp, r, &scene.parts);
            let g = results.status[i];
            assert!(
                g == cpu || g == CULL_VISIBLE,
                "camera {k} building {i}: GPU {g}, CPU {cpu}"
            );
            if seen.contains(citywalk_scenes::BuildingId(i as u32)) {
                assert_eq!(
                    g, CULL_VISIBLE,
                    "camera {k}: building {i} is seen but culled ({g})"
                );
            }
            occluded += usize::from(g == CULL_OCCLUDED);
            agree += usize::from(g == cpu);
            total += 1;
        }
        assert_eq!(
            results.commands.len(),
            results
                .status
                .iter()
                .filter(|s| **s == CULL_VISIBLE)
                .count(),
            "camera {k}: one command per visible building"
        );
    }
    eprintln!(
        "rendered city: {occluded} of {total} culled by occlusion, {agree} agree with the CPU"
    );
    assert!(
        occluded * 10 > total,
        "too little occlusion to test: {occluded} of {total}"
    );
    assert!(
        agree as f64 >= 0.999 * total as f64,
        "only {agree} of {total} agree"
    );
}
