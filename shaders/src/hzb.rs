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

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

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
