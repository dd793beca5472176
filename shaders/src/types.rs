//! `#[repr(C)]` twins of the WGSL structs the GPU reads. Each names its WGSL twin; the tests
//! check size and member offsets against naga's layout of the composed shader.

use bytemuck::{Pod, Zeroable};

/// Per-view uniforms. WGSL twin: `View` in `wgsl/shared/view.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct ViewUniforms {
    /// World to clip, column-major (`glam::Mat4::to_cols_array_2d`).
    pub view_proj: [[f32; 4]; 4],
    /// Eye position in metres (w unused).
    pub camera_position_m: [f32; 4],
    /// Unit vector towards the sun (w unused).
    pub sun_direction: [f32; 4],
    /// Linear RGB sky colour (a unused).
    pub sky_colour: [f32; 4],
    /// x: fog density per metre, y: viewport width px, z: viewport height px, w: the highlighted
    /// draw id + 1 (0: none; exact as f32 up to 2^24).
    pub params: [f32; 4],
}

/// One orthographic view of the cluster texture bake. WGSL twin: `BakeView` in
/// `wgsl/shared/view.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BakeView {
    /// World to clip, column-major, reversed Z.
    pub world_to_clip: [[f32; 4]; 4],
    /// x: the cluster's roof height (m), to which every building is scaled.
    pub params: [f32; 4],
}

/// One vertex of the scene's vertex buffer. WGSL twin: `SceneVertex` in
/// `wgsl/shared/scene.wgsl` (vertex attributes: `Float32x3` at 0, `Uint32` at 12).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct SceneVertex {
    pub position_m: [f32; 3],
    /// Building id, or [`crate::GROUND_ID`] for the ground plane.
    pub building_id: u32,
}

/// Per-building bounds and index range. WGSL twin: `BuildingRecord` in
/// `wgsl/shared/scene.wgsl`.
///
/// The building's triangles are `index_count` indices from `first_index` in the index buffer,
/// relative to `base_vertex`: exactly the fields of one [`DrawIndexedIndirectArgs`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct BuildingRecord {
    pub bounds_min_m: [f32; 3],
    pub first_index: u32,
    pub bounds_max_m: [f32; 3],
    pub index_count: u32,
    pub base_vertex: i32,
    pub vertex_count: u32,
    /// The building's tight cull bounds: parts `first_part..first_part + part_count` of the
    /// scene's [`CullPart`] buffer, which together contain every triangle of the building.
    /// `part_count` 0: the bounds above are all there is (cluster records, hand-made records).
    pub first_part: u32,
    pub part_count: u32,
}

impl BuildingRecord {
    /// The indirect draw of this building alone (one instance, `first_instance` = 0).
    pub fn draw_args(&self) -> DrawIndexedIndirectArgs {
        DrawIndexedIndirectArgs {
            index_count: self.index_count,
            instance_count: 1,
            first_index: self.first_index,
            base_vertex: self.base_vertex,
            first_instance: 0,
        }
    }
}

/// One part of a building's cull bounds: a prism whose floor is the convex quadrilateral
/// `corners_xy` (four x, y pairs in order around it, an oriented rectangle) and which reaches
/// from `z_min_m` to `z_max_m`. WGSL twin: `CullPart` in `wgsl/shared/scene.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct CullPart {
    pub corners_xy: [[f32; 4]; 2],
    pub z_min_m: f32,
    pub z_max_m: f32,
    pub _pad0: u32,
    pub _pad1: u32,
}

impl CullPart {
    /// The eight corners of the prism: the floor's four, then the roof's.
    pub fn corners(&self) -> [[f32; 3]; 8] {
        // Corner k is the first or the second pair of `corners_xy[k / 2]`.
        let xy = |k: usize| {
            let v = self.corners_xy[k / 2];
            let first = 2 * (k & 1);
            [v[first], v[first + 1]]
        };
        std::array::from_fn(|i| {
            let [x, y] = xy(i % 4);
            [x, y, if i < 4 { self.z_min_m } else { self.z_max_m }]
        })
    }
}

/// Arguments of one `draw_indexed_indirect`, in the order wgpu reads them. WGSL twin:
/// `DrawIndexedIndirectArgs` in `wgsl/shared/scene.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct DrawIndexedIndirectArgs {
    pub index_count: u32,
    pub instance_count: u32,
    pub first_index: u32,
    pub base_vertex: i32,
    pub first_instance: u32,
}

/// Per cluster tree node, where its mesh's textures lie (Chang et al. 2008 §7). WGSL twin:
/// `TexturedCluster` in `wgsl/shared/cluster_textures.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
pub struct TexturedCluster {
    /// The mesh's first vertex in the scene's vertex buffer (its record's `base_vertex`).
    pub base_vertex: u32,
    /// Its walls are `first_wall .. first_wall + wall_count` of the wall table.
    pub first_wall: u32,
    pub wall_count: u32,
    /// The page of its cells, or `NO_TEXTURE_PAGE`: drawn in flat colours.
    pub page: u32,
    /// The roof views' image in the page: x, y, width, height in texels.
    pub roof_rect_px: [f32; 4],
    /// The box the roof views see (xyz; `box_lo_m` w: the cluster's texture bin, for the
    /// bins debug view; `box_hi_m` w unused).
    pub box_lo_m: [f32; 4],
    pub box_hi_m: [f32; 4],
}

/// One wall of a textured cluster mesh. WGSL twin: `TexturedWall` in
/// `wgsl/shared/cluster_textures.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
pub struct TexturedWall {
    /// The wall's first hull vertex (x, y in metres).
    pub start_m: [f32; 2],
    /// Its direction divided by its length: `dot(p - start, along)` is 0 at the first vertex
    /// and 1 at the second.
    pub along_per_m: [f32; 2],
    /// Its image in the page's side view: x, y, width, height in texels (row 0 the wall's top).
    pub rect_px: [f32; 4],
}

/// What the textured scene pass needs besides the tables. WGSL twin: `ClusterTexturing` in
/// `wgsl/shared/cluster_textures.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
pub struct ClusterTexturingParams {
    /// The roof view of this frame (the one closest to the look vector): its image's right
    /// and down axes (xyz, unit; w unused).
    pub roof_right: [f32; 4],
    pub roof_down: [f32; 4],
    /// The side of every page, in texels.
    pub page_px: f32,
    /// Draw ids from here on are cluster nodes (`draw id - building_count`).
    pub building_count: u32,
    /// The roof view's index among a page's views (1..=5).
    pub roof_view: u32,
    /// How clusters are shaded: `CLUSTER_SHADING_FLAT`, `_TEXTURED` or `_BINS`.
    pub shading: u32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// naga's (span, member offsets by name) of struct `name` in `source`.
    fn naga_layout(source: &str, name: &str) -> (u32, Vec<(String, u32)>) {
        let module = naga::front::wgsl::parse_str(source).expect("composed WGSL parses");
        for (_, ty) in module.types.iter() {
            if ty.name.as_deref() == Some(name)
                && let naga::TypeInner::Struct { members, span } = &ty.inner
            {
                let members = members
                    .iter()
                    .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                    .collect();
                return (*span, members);
            }
        }
        panic!("struct {name} not found in WGSL");
    }

    fn check(name: &str, rust_size: usize, rust_offsets: &[(&str, usize)]) {
        for (file, source) in crate::ALL_WGSL {
            let (span, members) = naga_layout(source, name);
            assert_eq!(span as usize, rust_size, "{name} size in {file}");
            assert_eq!(members.len(), rust_offsets.len(), "{name} member count");
            for ((wgsl_name, wgsl_off), (rust_name, rust_off)) in members.iter().zip(rust_offsets) {
                assert_eq!(wgsl_name, rust_name, "{name} member order");
                assert_eq!(
                    *wgsl_off as usize, *rust_off,
                    "{name}.{rust_name} offset in {file}"
                );
            }
        }
    }

    #[test]
    fn cluster_texture_tables_match_wgsl() {
        check(
            "TexturedCluster",
            size_of::<TexturedCluster>(),
            &[
                ("base_vertex", offset_of!(TexturedCluster, base_vertex)),
                ("first_wall", offset_of!(TexturedCluster, first_wall)),
                ("wall_count", offset_of!(TexturedCluster, wall_count)),
                ("page", offset_of!(TexturedCluster, page)),
                ("roof_rect_px", offset_of!(TexturedCluster, roof_rect_px)),
                ("box_lo_m", offset_of!(TexturedCluster, box_lo_m)),
                ("box_hi_m", offset_of!(TexturedCluster, box_hi_m)),
            ],
        );
        check(
            "TexturedWall",
            size_of::<TexturedWall>(),
            &[
                ("start_m", offset_of!(TexturedWall, start_m)),
                ("along_per_m", offset_of!(TexturedWall, along_per_m)),
                ("rect_px", offset_of!(TexturedWall, rect_px)),
            ],
        );
        check(
            "ClusterTexturing",
            size_of::<ClusterTexturingParams>(),
            &[
                ("roof_right", offset_of!(ClusterTexturingParams, roof_right)),
                ("roof_down", offset_of!(ClusterTexturingParams, roof_down)),
                ("page_px", offset_of!(ClusterTexturingParams, page_px)),
                (
                    "building_count",
                    offset_of!(ClusterTexturingParams, building_count),
                ),
                ("roof_view", offset_of!(ClusterTexturingParams, roof_view)),
                ("shading", offset_of!(ClusterTexturingParams, shading)),
            ],
        );
    }

    #[test]
    fn bake_view_matches_wgsl() {
        check(
            "BakeView",
            size_of::<BakeView>(),
            &[
                ("world_to_clip", offset_of!(BakeView, world_to_clip)),
                ("params", offset_of!(BakeView, params)),
            ],
        );
    }

    #[test]
    fn view_uniforms_match_wgsl() {
        check(
            "View",
            size_of::<ViewUniforms>(),
            &[
                ("view_proj", offset_of!(ViewUniforms, view_proj)),
                (
                    "camera_position_m",
                    offset_of!(ViewUniforms, camera_position_m),
                ),
                ("sun_direction", offset_of!(ViewUniforms, sun_direction)),
                ("sky_colour", offset_of!(ViewUniforms, sky_colour)),
                ("params", offset_of!(ViewUniforms, params)),
            ],
        );
    }

    #[test]
    fn scene_vertex_matches_wgsl() {
        assert_eq!(size_of::<SceneVertex>(), 16);
        check(
            "SceneVertex",
            size_of::<SceneVertex>(),
            &[
                ("position_m", offset_of!(SceneVertex, position_m)),
                ("building_id", offset_of!(SceneVertex, building_id)),
            ],
        );
    }

    #[test]
    fn building_record_matches_wgsl() {
        check(
            "BuildingRecord",
            size_of::<BuildingRecord>(),
            &[
                ("bounds_min_m", offset_of!(BuildingRecord, bounds_min_m)),
                ("first_index", offset_of!(BuildingRecord, first_index)),
                ("bounds_max_m", offset_of!(BuildingRecord, bounds_max_m)),
                ("index_count", offset_of!(BuildingRecord, index_count)),
                ("base_vertex", offset_of!(BuildingRecord, base_vertex)),
                ("vertex_count", offset_of!(BuildingRecord, vertex_count)),
                ("first_part", offset_of!(BuildingRecord, first_part)),
                ("part_count", offset_of!(BuildingRecord, part_count)),
            ],
        );
    }

    #[test]
    fn cull_part_matches_wgsl() {
        check(
            "CullPart",
            size_of::<CullPart>(),
            &[
                ("corners_xy", offset_of!(CullPart, corners_xy)),
                ("z_min_m", offset_of!(CullPart, z_min_m)),
                ("z_max_m", offset_of!(CullPart, z_max_m)),
                ("_pad0", offset_of!(CullPart, _pad0)),
                ("_pad1", offset_of!(CullPart, _pad1)),
            ],
        );
    }

    #[test]
    fn draw_indexed_indirect_args_match_wgsl_and_wgpu() {
        // wgpu reads five consecutive 32-bit words.
        assert_eq!(size_of::<DrawIndexedIndirectArgs>(), 20);
        check(
            "DrawIndexedIndirectArgs",
            size_of::<DrawIndexedIndirectArgs>(),
            &[
                (
                    "index_count",
                    offset_of!(DrawIndexedIndirectArgs, index_count),
                ),
                (
                    "instance_count",
                    offset_of!(DrawIndexedIndirectArgs, instance_count),
                ),
                (
                    "first_index",
                    offset_of!(DrawIndexedIndirectArgs, first_index),
                ),
                (
                    "base_vertex",
                    offset_of!(DrawIndexedIndirectArgs, base_vertex),
                ),
                (
                    "first_instance",
                    offset_of!(DrawIndexedIndirectArgs, first_instance),
                ),
            ],
        );
    }

    /// The value of WGSL `const name` in `source`, evaluated by naga.
    fn wgsl_const(module: &naga::Module, name: &str) -> naga::Literal {
        let (_, c) = module
            .constants
            .iter()
            .find(|(_, c)| c.name.as_deref() == Some(name))
            .unwrap_or_else(|| panic!("WGSL const {name} missing"));
        match module.global_expressions[c.init] {
            naga::Expression::Literal(l) => l,
            ref other => panic!("WGSL const {name} is not a literal: {other:?}"),
        }
    }

    #[test]
    fn wgsl_constants_equal_the_rust_ones() {
        for (file, source) in crate::ALL_WGSL {
            let module = naga::front::wgsl::parse_str(source).expect("parses");
            for (name, value) in crate::constants::WGSL_U32 {
                assert_eq!(
                    wgsl_const(&module, name),
                    naga::Literal::U32(*value),
                    "{name} in {file}"
                );
            }
            for (name, value) in crate::constants::WGSL_F32 {
                assert_eq!(
                    wgsl_const(&module, name),
                    naga::Literal::F32(*value),
                    "{name} in {file}"
                );
            }
        }
        assert_eq!(crate::constants::GROUND_ID, u32::MAX);
        assert_ne!(crate::ID_BACKGROUND, crate::ID_OFFSET);
    }
}
