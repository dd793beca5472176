//! The virtual occluders on the GPU and their per-frame selection by projected size (Germs &
//! Jansen 2001 build them offline; the pre-pass draws the ones near the camera).

use citywalk_scenes::frustum::{Containment, Frustum};
use citywalk_scenes::occluder::OccluderSet;
use citywalk_scenes::occluder_draws::{OccluderArrays, OccluderArraysView, OccluderRecord};
use citywalk_scenes::package::GpuSceneView;
use citywalk_shaders::DrawIndexedIndirectArgs;
use glam::Vec3;

use crate::camera::Camera;
use crate::frame::sphere_index::SphereIndex;
use crate::gpu::GpuContext;
use crate::upload::{UploadError, array_buffer, buffer_from_chunks};

/// One occluder on the GPU: its draw and its bounds for the CPU selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OccluderDraw {
    pub building: u32,
    pub draw: DrawIndexedIndirectArgs,
    pub bounds_min_m: Vec3,
    pub bounds_max_m: Vec3,
    pub triangles: u32,
}

impl OccluderDraw {
    fn of(r: &OccluderRecord) -> OccluderDraw {
        let (lo, hi) = r.bounds();
        OccluderDraw {
            building: r.building,
            draw: DrawIndexedIndirectArgs {
                index_count: r.index_count,
                instance_count: 1,
                first_index: r.first_index,
                // The index buffer holds absolute indices ([`absolute_index_buffer`]).
                base_vertex: 0,
                first_instance: 0,
            },
            bounds_min_m: lo,
            bounds_max_m: hi,
            triangles: r.index_count / 3,
        }
    }
}

/// Every occluder mesh of a scene in one vertex and one index buffer, with per-occluder ranges.
#[derive(Debug)]
pub struct OccluderMeshes {
    pub(super) vertex_buffer: wgpu::Buffer,
    pub(super) index_buffer: wgpu::Buffer,
    /// One entry per occluder with a non-empty mesh.
    pub occluders: Vec<OccluderDraw>,
    /// The spheres binned by radius, centres in R-trees: the selection visits only those near
    /// enough to be wanted.
    index: SphereIndex,
}

/// The bounding sphere of an occluder's box (centre, radius in metres).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sphere {
    centre_m: Vec3,
    radius_m: f32,
}

impl Sphere {
    fn of(o: &OccluderDraw) -> Sphere {
        Sphere {
            centre_m: (o.bounds_min_m + o.bounds_max_m) * 0.5,
            radius_m: (o.bounds_max_m - o.bounds_min_m).length() * 0.5,
        }
    }
}

impl OccluderMeshes {
    /// Uploads every drawable occluder of `set` ([`OccluderArrays::of`]: vertices carry the
    /// occluder's building id; triangles with an index outside their mesh and non-finite meshes
    /// are left out).
    pub fn upload(gpu: &GpuContext, set: &OccluderSet) -> Result<OccluderMeshes, UploadError> {
        Self::upload_arrays(gpu, OccluderArrays::of(set).view(), &|_| {})
    }

    /// Uploads the occluders of a package's GPU scene, straight from its mapping (whose pages
    /// are released as they are uploaded).
    pub fn upload_package(
        gpu: &GpuContext,
        scene: &GpuSceneView<'_>,
    ) -> Result<OccluderMeshes, UploadError> {
        Self::upload_arrays(gpu, scene.occluders, &|bytes| scene.release_resident(bytes))
    }

    fn upload_arrays(
        gpu: &GpuContext,
        arrays: OccluderArraysView<'_>,
        release: &dyn Fn(&[u8]),
    ) -> Result<OccluderMeshes, UploadError> {
        let occluders: Vec<OccluderDraw> = arrays.records.iter().map(OccluderDraw::of).collect();
        // Buffers are never empty, so they can always be bound.
        let vertex_buffer = array_buffer(
            gpu,
            "occluder vertices",
            arrays.vertices,
            wgpu::BufferUsages::VERTEX,
            release,
        )?;
        let index_buffer = absolute_index_buffer(gpu, &arrays, release)?;
        Ok(OccluderMeshes {
            vertex_buffer,
            index_buffer,
            index: SphereIndex::new(
                occluders
                    .iter()
                    .map(Sphere::of)
                    .map(|s| (s.centre_m, s.radius_m)),
            ),
            occluders,
        })
    }

    /// The occluders to draw for `camera` on a viewport `height_px` tall: in the frustum, and
    /// whose bounding sphere projects to more than `min_px` pixels (or contains the eye). The
    /// early set lives on the GPU, so an occluder of a building drawn early is drawn as well
    /// (it lies inside the building: it hides nothing more).
    pub fn select(
        &self,
        camera: &Camera,
        frustum: &Frustum,
        height_px: u32,
        min_px: f32,
    ) -> Vec<usize> {
        let px_per_rad = height_px as f32 / (camera.fov_y_rad * 0.5).tan();
        // The index holds the occluders it was made with (`occluders` is public).
        let indexed = self.index.len() == self.occluders.len();
        select_occluders(
            &self.occluders,
            indexed.then_some(&self.index),
            camera.position,
            frustum,
            px_per_rad,
            min_px,
        )
    }
}

impl OccluderMeshes {
    /// The vertex buffer and the index buffer (absolute indices: every occluder's range
    /// `first_index .. first_index + index_count` draws with base vertex 0).
    pub fn buffers(&self) -> (&wgpu::Buffer, &wgpu::Buffer) {
        (&self.vertex_buffer, &self.index_buffer)
    }

    /// The draws of the `selected` occluders, those adjacent in the index buffer merged into one
    /// draw (the buffer holds absolute indices, so any run of adjacent ranges is one range), in
    /// index order. Occluders of one block lie together in the arrays, so the hundreds to
    /// thousands a street frame selects are far fewer draws: on lavapipe each draw of a
    /// multi-draw costs microseconds of set-up whatever its size.
    pub fn merged_draws(&self, selected: &[usize]) -> Vec<DrawIndexedIndirectArgs> {
        let mut ranges: Vec<(u32, u32)> = selected
            .iter()
            .filter_map(|&i| self.occluders.get(i))
            .map(|o| (o.draw.first_index, o.draw.index_count))
            .collect();
        merge_ranges(&mut ranges);
        ranges
            .into_iter()
            .map(|(first_index, index_count)| DrawIndexedIndirectArgs {
                index_count,
                instance_count: 1,
                first_index,
                base_vertex: 0,
                first_instance: 0,
            })
            .collect()
    }
}

/// Sorts index ranges `(first, count)` and merges those that touch or overlap.
fn merge_ranges(ranges: &mut Vec<(u32, u32)>) {
    ranges.sort_unstable();
    let mut merged: Vec<(u32, u32)> = Vec::with_capacity(ranges.len());
    for &(first, count) in ranges.iter() {
        let end = u64::from(first) + u64::from(count);
        match merged.last_mut() {
            Some((f, c)) if u64::from(*f) + u64::from(*c) >= u64::from(first) => {
                let new_end = end.max(u64::from(*f) + u64::from(*c));
                *c = (new_end - u64::from(*f)) as u32;
            }
            _ => merged.push((first, count)),
        }
    }
    *ranges = merged;
}

/// The occluders' index buffer with every index made absolute (its record's base vertex added),
/// made chunk by chunk in the buffer's order ([`buffer_from_chunks`]: no second copy of all the
/// indices). Indices outside every record are never drawn and stay zero; at least one
/// triangle long, so it can always be bound. The records' and each chunk's source bytes go to
/// `release` once read.
fn absolute_index_buffer(
    gpu: &GpuContext,
    arrays: &OccluderArraysView<'_>,
    release: &dyn Fn(&[u8]),
) -> Result<wgpu::Buffer, UploadError> {
    const U32: usize = size_of::<u32>();
    let len = arrays.indices.len().max(3);
    /// What the indices need of a record: its index range and base vertex.
    #[derive(Clone, Copy)]
    struct Range {
        first: usize,
        end: usize,
        base_vertex: u32,
    }
    // Records by first index: each chunk then reads the records from the first one that has
    // not ended before it (ranges may be empty; they do not overlap in a valid package, but a
    // later record that did would still be written).
    let mut order: Vec<Range> = arrays
        .records
        .iter()
        .map(|r| Range {
            first: r.first_index as usize,
            end: (r.first_index as usize).saturating_add(r.index_count as usize),
            base_vertex: r.base_vertex,
        })
        .collect();
    release(bytemuck::cast_slice(arrays.records));
    order.sort_by_key(|r| r.first);
    let mut next = 0;
    buffer_from_chunks(
        gpu,
        "occluder indices",
        len * U32,
        wgpu::BufferUsages::INDEX,
        |bytes, out| {
            let chunk = bytes.start / U32..bytes.end / U32;
            while order.get(next).is_some_and(|r| r.end <= chunk.start) {
                next += 1;
            }
            let out: &mut [u32] = bytemuck::cast_slice_mut(out);
            for r in order[next..].iter().take_while(|r| r.first < chunk.end) {
                let (from, to) = (r.first.max(chunk.start), r.end.min(chunk.end));
                let Some(source) = arrays.indices.get(from..to) else {
                    continue;
                };
                let target = &mut out[from - chunk.start..to - chunk.start];
                for (t, i) in target.iter_mut().zip(source) {
                    *t = i.wrapping_add(r.base_vertex);
                }
            }
            let read = chunk.start.min(arrays.indices.len())..chunk.end.min(arrays.indices.len());
            release(bytemuck::cast_slice(&arrays.indices[read]));
        },
    )
}

/// [`OccluderMeshes::select`] over `occluders` (and the index of their spheres,
/// [`Sphere::of`], when there is one): the indices of those [`occluder_wanted`] admits,
/// ascending. The spheres are made again from the boxes as they are tested (a few thousand
/// a frame through the index), not kept: at a million buildings they would be 24 MB.
fn select_occluders(
    occluders: &[OccluderDraw],
    index: Option<&SphereIndex>,
    eye: Vec3,
    frustum: &Frustum,
    px_per_rad: f32,
    min_px: f32,
) -> Vec<usize> {
    // A cheap pre-filter before the exact test: an occluder projects to more than `min_px`
    // only within `radius · max(1, px_per_rad / min_px)` of the eye (a squared distance, no
    // root); the margin keeps it from rejecting anything the exact test's rounding admits.
    let reach_per_radius = (px_per_rad / min_px).max(1.0) * (1.0 + 1e-3);
    let prefilter = min_px > 0.0 && reach_per_radius.is_finite();
    let wanted = |i: usize| {
        let o = &occluders[i];
        let sphere = Sphere::of(o);
        if prefilter {
            let reach_m = sphere.radius_m * reach_per_radius;
            if sphere.centre_m.distance_squared(eye) > reach_m * reach_m {
                return false;
            }
        }
        occluder_wanted(o, sphere, eye, frustum, px_per_rad, min_px)
    };
    match index {
        Some(index) if prefilter => index
            .near(eye, reach_per_radius, frustum)
            .into_iter()
            .filter(|&i| wanted(i))
            .collect(),
        _ => (0..occluders.len()).filter(|&i| wanted(i)).collect(),
    }
}

/// Whether an occluder is near enough to draw: its bounding sphere contains the eye or projects
/// to more than `min_px` pixels (`px_per_rad`: viewport height over `tan(fov_y / 2)`), and its
/// box is not outside the frustum.
fn occluder_wanted(
    o: &OccluderDraw,
    sphere: Sphere,
    eye: Vec3,
    frustum: &Frustum,
    px_per_rad: f32,
    min_px: f32,
) -> bool {
    let Sphere { centre_m, radius_m } = sphere;
    let distance_m = centre_m.distance(eye);
    (distance_m <= radius_m || radius_m / distance_m * px_per_rad > min_px)
        && frustum.classify_aabb(o.bounds_min_m, o.bounds_max_m) != Containment::Outside
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacent_and_overlapping_index_ranges_merge_and_gaps_do_not() {
        let mut ranges = vec![(30, 6), (0, 3), (3, 6), (12, 3), (9, 3), (33, 3), (100, 0)];
        merge_ranges(&mut ranges);
        assert_eq!(ranges, vec![(0, 15), (30, 6), (100, 0)]);
        let mut none = Vec::new();
        merge_ranges(&mut none);
        assert!(none.is_empty());
        // Ranges ending at u32::MAX do not overflow.
        let mut high = vec![(u32::MAX - 3, 3), (u32::MAX - 6, 3)];
        merge_ranges(&mut high);
        assert_eq!(high, vec![(u32::MAX - 6, 6)]);
    }
    use crate::frame::DEFAULT_OCCLUDER_MIN_PX;

    #[test]
    fn occluders_are_wanted_by_projected_size_and_frustum() {
        let camera = Camera::new(Vec3::ZERO, 0.0, 0.0);
        let height_px = 720;
        let px_per_rad = height_px as f32 / (camera.fov_y_rad * 0.5).tan();
        let frustum = Frustum::from_view_proj(camera.view_proj(16.0 / 9.0));
        // A 10 m cube (radius ≈ 8.66 m) straight ahead at distance d projects to
        // 8.66 / d · 1247 px: more than 24 px up to d ≈ 450 m, more than the default 12 px up
        // to d ≈ 900 m.
        let min_px = 24.0;
        let cube = |centre: Vec3| OccluderDraw {
            building: 0,
            draw: DrawIndexedIndirectArgs {
                index_count: 3,
                instance_count: 1,
                first_index: 0,
                base_vertex: 0,
                first_instance: 0,
            },
            bounds_min_m: centre - Vec3::splat(5.0),
            bounds_max_m: centre + Vec3::splat(5.0),
            triangles: 1,
        };
        let wanted = |centre: Vec3| {
            let o = cube(centre);
            occluder_wanted(
                &o,
                Sphere::of(&o),
                camera.position,
                &frustum,
                px_per_rad,
                min_px,
            )
        };
        assert!(wanted(Vec3::new(50.0, 0.0, 0.0)));
        assert!(wanted(Vec3::new(400.0, 0.0, 0.0)));
        assert!(!wanted(Vec3::new(470.0, 0.0, 0.0)));
        // Behind the eye: outside the frustum however large.
        assert!(!wanted(Vec3::new(-20.0, 0.0, 0.0)));
        // Around the eye: always.
        assert!(wanted(Vec3::new(1.0, 0.0, 0.0)));
    }

    #[test]
    fn the_distance_prefilter_selects_exactly_what_the_exact_test_admits() {
        // Occluders of many sizes scattered around the eye (a fixed-seed LCG), some of them
        // right at the projected-size threshold.
        let camera = Camera::new(Vec3::new(3.0, -2.0, 1.7), 0.4, 0.05);
        let frustum = Frustum::from_view_proj(camera.view_proj(16.0 / 9.0));
        let px_per_rad = 720.0 / (camera.fov_y_rad * 0.5).tan();
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let occluders: Vec<OccluderDraw> = (0..4000)
            .map(|i| {
                let centre = Vec3::new(
                    next() * 2000.0 - 1000.0,
                    next() * 2000.0 - 1000.0,
                    next() * 40.0,
                );
                let half = Vec3::new(next(), next(), next()) * 30.0 + Vec3::splat(0.1);
                OccluderDraw {
                    building: i % 50,
                    draw: DrawIndexedIndirectArgs {
                        index_count: 3,
                        instance_count: 1,
                        first_index: 0,
                        base_vertex: 0,
                        first_instance: 0,
                    },
                    bounds_min_m: centre - half,
                    bounds_max_m: centre + half,
                    triangles: 1,
                }
            })
            .collect();
        for min_px in [DEFAULT_OCCLUDER_MIN_PX, 1.0, 48.0, 0.0, -1.0, f32::NAN] {
            let exact: Vec<usize> = (0..occluders.len())
                .filter(|&i| {
                    occluder_wanted(
                        &occluders[i],
                        Sphere::of(&occluders[i]),
                        camera.position,
                        &frustum,
                        px_per_rad,
                        min_px,
                    )
                })
                .collect();
            let index = SphereIndex::new(
                occluders
                    .iter()
                    .map(Sphere::of)
                    .map(|s| (s.centre_m, s.radius_m)),
            );
            let indexed = select_occluders(
                &occluders,
                Some(&index),
                camera.position,
                &frustum,
                px_per_rad,
                min_px,
            );
            assert_eq!(indexed, exact, "min_px {min_px}, indexed");
            let selected = select_occluders(
                &occluders,
                None,
                camera.position,
                &frustum,
                px_per_rad,
                min_px,
            );
            assert_eq!(selected, exact, "min_px {min_px}");
            if min_px == DEFAULT_OCCLUDER_MIN_PX {
                assert!(!exact.is_empty() && exact.len() < occluders.len() / 2);
            }
        }
    }
}
