//! `#[repr(C)]` twins of the hierarchical-Z passes' WGSL structs (`wgsl/hzb_cull.wgsl`), with a
//! test against naga's layout of the composed shader.

use bytemuck::{Pod, Zeroable};

/// Uniforms of the cull pass. WGSL twin: `HzbCullParams` in `wgsl/hzb_cull.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct HzbCullParams {
    /// World to clip, reversed-Z, column-major (`glam::Mat4::to_cols_array_2d`).
    pub view_proj: [[f32; 4]; 4],
    /// Viewport (= pyramid level 0) width and height in pixels.
    pub viewport_px: [u32; 2],
    /// Number of boxes to test.
    pub box_count: u32,
    /// Number of pyramid levels.
    pub level_count: u32,
    /// The frame's visibility stamp: the cull marks each visible candidate's draw id with it;
    /// the early entry points take a draw id marked with `frame_stamp - 1` (or under a cluster
    /// so marked) as visible last frame.
    pub frame_stamp: u32,
    /// Draw ids below this are buildings (drawn early when visible last frame); the others are
    /// cluster meshes (never drawn early).
    pub building_count: u32,
    /// Bit [`CULL_FLAG_DRAW_IDS`](crate::constants::CULL_FLAG_DRAW_IDS): box `i` stands for draw
    /// id `draw_ids[i]` (else draw id `i`); bit
    /// [`CULL_FLAG_VISIBILITY`](crate::constants::CULL_FLAG_VISIBILITY): the stamps and parents
    /// are bound (else nothing is read or marked).
    pub flags: u32,
    pub _pad: u32,
}

/// Uniforms of the tree cull, the GPU's LOD cut with hierarchical occlusion culling (engine
/// `hzb::tree_cull`). WGSL twin: `TreeCullParams` in `wgsl/hzb_cull.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct TreeCullParams {
    /// Eye position in metres.
    pub eye_m: [f32; 3],
    /// Pixels per metre at 1 m: `height_px / (2·tan(fov_y/2))` (engine `lod::LodView`).
    pub px_per_m_at_1m: f32,
    /// [`TREE_CRITERION_CHANG`](crate::constants::TREE_CRITERION_CHANG),
    /// [`TREE_CRITERION_YANG`](crate::constants::TREE_CRITERION_YANG) or
    /// [`TREE_CRITERION_GEOMETRIC`](crate::constants::TREE_CRITERION_GEOMETRIC).
    pub criterion: u32,
    /// Chang ε (px²), Yang δh (px) or the geometric tolerance (px).
    pub tolerance_a: f32,
    /// Chang τ (px) or Yang δa (px²); unused by the geometric criterion.
    pub tolerance_b: f32,
    /// The tree's root node.
    pub root: u32,
    /// Entries of each half of the kept lists.
    pub list_capacity: u32,
    /// The half of the kept lists holding last frame's kept draw ids (0 or 1); this frame
    /// writes the other.
    pub last_half: u32,
    /// [`TREE_EARLY_NONE`](crate::constants::TREE_EARLY_NONE) (no last frame to draw early) or
    /// [`TREE_EARLY_FRUSTUM`](crate::constants::TREE_EARLY_FRUSTUM).
    pub early: u32,
    /// Entries of the node queue (the tree's node count).
    pub queue_capacity: u32,
    /// This frame's mark in the drawn-early buffer (per draw id).
    pub early_mark: u32,
    /// Number of tree nodes.
    pub node_count: u32,
    /// Draw ids below this are buildings, `building_count + n` is node `n`'s cluster mesh.
    pub building_count: u32,
    /// Workgroups of each early and level dispatch, which stride over their entries (fewer on
    /// a software adapter: engine `hzb::tree_cull`).
    pub walk_workgroups: u32,
}

/// One cluster tree node as the tree cull reads it. WGSL twin: `TreeNode` in
/// `wgsl/hzb_cull.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct TreeNode {
    /// The node's bounds (the LOD cut's distance is to these).
    pub bounds_min_m: [f32; 3],
    /// Children `children[first_child .. first_child + child_count]`.
    pub first_child: u32,
    pub bounds_max_m: [f32; 3],
    pub child_count: u32,
    /// Parent node, or [`NO_PARENT`](crate::constants::NO_PARENT) at the root.
    pub parent: u32,
    /// A leaf's building (draw id); `NO_PARENT` for an inner node.
    pub building: u32,
    /// Buildings below the node.
    pub building_count: u32,
    /// Landmarks `landmarks[first_landmark .. first_landmark + landmark_count]`.
    pub first_landmark: u32,
    pub landmark_count: u32,
    /// The cluster mesh's roof height (`ClusterNode::height_m`), metres.
    pub height_m: f32,
    /// Chang: `|(d·h, w·h, w·d)|` of the negative-space box (m²), the largest area it shows.
    pub chang_area_m2: f32,
    /// Yang: Δh (m).
    pub delta_h_m: f32,
    /// Yang: Δa (m²).
    pub delta_a_m2: f32,
    /// 1 when any error is positive (refined whenever the eye is inside the bounds).
    pub has_error: u32,
    /// The geometric criterion's error (m): the larger of the node's geometric and colour
    /// errors (scenes `ClusterNode::lod_error_m`).
    pub lod_error_m: f32,
    pub _pad: u32,
}

/// A landmark candidate of a node: its building and the building's top. WGSL twin:
/// `TreeLandmark` in `wgsl/hzb_cull.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct TreeLandmark {
    pub building: u32,
    pub top_m: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// Size and member offsets of the WGSL struct `name` of the cull shader.
    fn wgsl_layout(name: &str) -> (u32, Vec<(String, u32)>) {
        let module = naga::front::wgsl::parse_str(crate::HZB_CULL_WGSL).expect("parses");
        module
            .types
            .iter()
            .find_map(|(_, ty)| match &ty.inner {
                naga::TypeInner::Struct { members, span } if ty.name.as_deref() == Some(name) => {
                    Some((
                        *span,
                        members
                            .iter()
                            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
                            .collect(),
                    ))
                }
                _ => None,
            })
            .unwrap_or_else(|| panic!("{name} in hzb_cull.wgsl"))
    }

    /// The cull shaders read their per-frame parameters from storage, never from a uniform
    /// buffer: lavapipe recompiles a shader whenever an inlinable uniform value changes (see
    /// `wgsl/hzb_cull.wgsl`), a stall of up to seconds in every frame whose parameters are new.
    #[test]
    fn cull_parameters_are_not_uniform_buffers() {
        let module = naga::front::wgsl::parse_str(crate::HZB_CULL_WGSL).expect("parses");
        let uniforms: Vec<_> = module
            .global_variables
            .iter()
            .filter(|(_, v)| v.space == naga::AddressSpace::Uniform)
            .map(|(_, v)| v.name.clone().unwrap_or_default())
            .collect();
        assert!(
            uniforms.is_empty(),
            "uniform buffers in hzb_cull.wgsl: {uniforms:?}"
        );
        let storage_params = ["params", "tree"].map(|name| {
            module.global_variables.iter().any(|(_, v)| {
                v.name.as_deref() == Some(name)
                    && matches!(v.space, naga::AddressSpace::Storage { .. })
            })
        });
        assert_eq!(storage_params, [true, true]);
    }

    #[test]
    fn tree_structs_match_wgsl() {
        let (span, members) = wgsl_layout("TreeCullParams");
        assert_eq!(span as usize, size_of::<TreeCullParams>());
        let rust = [
            ("eye_m", offset_of!(TreeCullParams, eye_m)),
            ("px_per_m_at_1m", offset_of!(TreeCullParams, px_per_m_at_1m)),
            ("criterion", offset_of!(TreeCullParams, criterion)),
            ("tolerance_a", offset_of!(TreeCullParams, tolerance_a)),
            ("tolerance_b", offset_of!(TreeCullParams, tolerance_b)),
            ("root", offset_of!(TreeCullParams, root)),
            ("list_capacity", offset_of!(TreeCullParams, list_capacity)),
            ("last_half", offset_of!(TreeCullParams, last_half)),
            ("early", offset_of!(TreeCullParams, early)),
            ("queue_capacity", offset_of!(TreeCullParams, queue_capacity)),
            ("early_mark", offset_of!(TreeCullParams, early_mark)),
            ("node_count", offset_of!(TreeCullParams, node_count)),
            ("building_count", offset_of!(TreeCullParams, building_count)),
            (
                "walk_workgroups",
                offset_of!(TreeCullParams, walk_workgroups),
            ),
        ];
        assert_eq!(members.len(), rust.len());
        for ((name, offset), (want, at)) in members.iter().zip(rust) {
            assert_eq!((name.as_str(), *offset as usize), (want, at));
        }
        let (span, members) = wgsl_layout("TreeNode");
        assert_eq!(span as usize, size_of::<TreeNode>());
        let rust = [
            ("bounds_min_m", offset_of!(TreeNode, bounds_min_m)),
            ("first_child", offset_of!(TreeNode, first_child)),
            ("bounds_max_m", offset_of!(TreeNode, bounds_max_m)),
            ("child_count", offset_of!(TreeNode, child_count)),
            ("parent", offset_of!(TreeNode, parent)),
            ("building", offset_of!(TreeNode, building)),
            ("building_count", offset_of!(TreeNode, building_count)),
            ("first_landmark", offset_of!(TreeNode, first_landmark)),
            ("landmark_count", offset_of!(TreeNode, landmark_count)),
            ("height_m", offset_of!(TreeNode, height_m)),
            ("chang_area_m2", offset_of!(TreeNode, chang_area_m2)),
            ("delta_h_m", offset_of!(TreeNode, delta_h_m)),
            ("delta_a_m2", offset_of!(TreeNode, delta_a_m2)),
            ("has_error", offset_of!(TreeNode, has_error)),
            ("lod_error_m", offset_of!(TreeNode, lod_error_m)),
            ("_pad", offset_of!(TreeNode, _pad)),
        ];
        assert_eq!(members.len(), rust.len());
        for ((name, offset), (want, at)) in members.iter().zip(rust) {
            assert_eq!((name.as_str(), *offset as usize), (want, at));
        }
        let (span, _) = wgsl_layout("TreeLandmark");
        assert_eq!(span as usize, size_of::<TreeLandmark>());
    }

    #[test]
    fn hzb_cull_params_match_wgsl() {
        let module = naga::front::wgsl::parse_str(crate::HZB_CULL_WGSL).expect("parses");
        let (span, members) = module
            .types
            .iter()
            .find_map(|(_, ty)| match &ty.inner {
                naga::TypeInner::Struct { members, span }
                    if ty.name.as_deref() == Some("HzbCullParams") =>
                {
                    Some((*span, members.clone()))
                }
                _ => None,
            })
            .expect("HzbCullParams in hzb_cull.wgsl");
        assert_eq!(span as usize, size_of::<HzbCullParams>());
        let rust = [
            ("view_proj", offset_of!(HzbCullParams, view_proj)),
            ("viewport_px", offset_of!(HzbCullParams, viewport_px)),
            ("box_count", offset_of!(HzbCullParams, box_count)),
            ("level_count", offset_of!(HzbCullParams, level_count)),
            ("frame_stamp", offset_of!(HzbCullParams, frame_stamp)),
            ("building_count", offset_of!(HzbCullParams, building_count)),
            ("flags", offset_of!(HzbCullParams, flags)),
            ("_pad", offset_of!(HzbCullParams, _pad)),
        ];
        assert_eq!(members.len(), rust.len());
        for (m, (name, offset)) in members.iter().zip(rust) {
            assert_eq!(m.name.as_deref(), Some(name));
            assert_eq!(m.offset as usize, offset, "{name}");
        }
    }
}
