//! `#[repr(C)]` twins of the debug views' WGSL structs (`wgsl/debug_*.wgsl`), with a test
//! against naga's layout of the composed shader.

use bytemuck::{Pod, Zeroable};

/// Uniforms of the pyramid debug view. WGSL twin: `PyramidViewParams` in
/// `wgsl/debug_pyramid.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct PyramidViewParams {
    /// Pyramid level shown.
    pub level: u32,
    /// Logical size of that level in texels.
    pub level_width: u32,
    pub level_height: u32,
    /// 1 when the target is sRGB-encoded (the grey is decoded so the screen shows it).
    pub srgb_target: u32,
    /// Near plane (m): reversed-Z depth `d` lies at distance `near_m / d`.
    pub near_m: f32,
    /// Distances drawn white and black (m).
    pub white_m: f32,
    pub black_m: f32,
    pub _pad: f32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    #[test]
    fn pyramid_view_params_match_wgsl() {
        let module = naga::front::wgsl::parse_str(crate::DEBUG_PYRAMID_WGSL).expect("parses");
        let (span, members) = module
            .types
            .iter()
            .find_map(|(_, ty)| match &ty.inner {
                naga::TypeInner::Struct { members, span }
                    if ty.name.as_deref() == Some("PyramidViewParams") =>
                {
                    Some((*span, members.clone()))
                }
                _ => None,
            })
            .expect("PyramidViewParams in debug_pyramid.wgsl");
        assert_eq!(span as usize, size_of::<PyramidViewParams>());
        let rust = [
            ("level", offset_of!(PyramidViewParams, level)),
            ("level_width", offset_of!(PyramidViewParams, level_width)),
            ("level_height", offset_of!(PyramidViewParams, level_height)),
            ("srgb_target", offset_of!(PyramidViewParams, srgb_target)),
            ("near_m", offset_of!(PyramidViewParams, near_m)),
            ("white_m", offset_of!(PyramidViewParams, white_m)),
            ("black_m", offset_of!(PyramidViewParams, black_m)),
            ("_pad", offset_of!(PyramidViewParams, _pad)),
        ];
        assert_eq!(members.len(), rust.len());
        for (m, (name, offset)) in members.iter().zip(rust) {
            assert_eq!(m.name.as_deref(), Some(name));
            assert_eq!(m.offset as usize, offset, "{name}");
        }
    }
}
