//! citywalk shaders: the WGSL sources (validated by naga in `build.rs`, so a broken shader
//! breaks the build) and the `#[repr(C)]` Pod twins of every struct the GPU reads.
//!
//! Each `*_WGSL` constant is the composed source of one shader: the constants of
//! [`constants`] emitted as WGSL, then every `wgsl/shared/*.wgsl`, then the shader's own file.

/// Constants shared by Rust and WGSL, defined once (emitted into WGSL by `build.rs`).
pub mod constants {
    include!("constants.rs");
}

mod debug;
mod hzb;
mod types;

pub use constants::{GROUND_ID, ID_BACKGROUND, ID_OFFSET, SURFACE_ID_BASE, depth_tie_factor};
pub use debug::PyramidViewParams;
pub use hzb::{HzbCullParams, TreeCullParams, TreeLandmark, TreeNode};
pub use types::{
    BakeView, BuildingRecord, ClusterTexturingParams, CullPart, DrawIndexedIndirectArgs,
    SceneVertex, TexturedCluster, TexturedWall, ViewUniforms,
};

/// What every shader below starts with: the constants and every `wgsl/shared/*.wgsl`. A test
/// composes its own entry points with it to run a shared helper on the GPU against its CPU
/// reference (`tests/tests/cluster_textures.rs` does so for the texel mappings).
pub const SHARED_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/shared.wgsl"));

/// Flat-shaded scene pass (`wgsl/scene.wgsl`): entry points `vs_main`, `fs_main`; group 0
/// binding 0 is the [`ViewUniforms`] uniform; vertex buffer of [`SceneVertex`]. Entry point
/// `fs_textured` also draws cluster meshes with their baked textures, from group 1: binding 0
/// the [`ClusterTexturingParams`] uniform, 1 the [`TexturedCluster`]s by tree node, 2 the
/// [`TexturedWall`]s, 3 the resident layer of every page view (`u32`, page × 6 + view), 4
/// the resident page views (`texture_2d_array<f32>`, filterable), 5 a filtering sampler.
pub const SCENE_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/scene.wgsl"));

/// Building-id pass (`wgsl/ids.wgsl`): like [`SCENE_WGSL`] but writes `id + ID_OFFSET` to an
/// `R32Uint` target, [`ID_BACKGROUND`] for the ground.
pub const IDS_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/ids.wgsl"));

/// Hierarchical-Z pyramid build (`wgsl/hzb_build.wgsl`): entry points `copy_depth` and
/// `merge_depths` (group 0: binding 0 the depth buffer and binding 5 the depth merged into it, as
/// unfilterable `texture_2d<f32>`; bindings 1 and 6 levels 0 and 1 as write-only `r32float`
/// storage textures; one invocation per level-1 texel) and `reduce` (binding 2 level l
/// read-only, binding 3 level l + 1 write-only, binding 4 a `vec4<u32>` uniform: logical sizes of
/// level l (xy) and l + 1 (zw)).
pub const HZB_BUILD_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/hzb_build.wgsl"));

/// Hierarchical-Z occlusion cull (`wgsl/hzb_cull.wgsl`): entry points `cull`, `early` and
/// `gate`; group 0: binding 0 the [`HzbCullParams`] uniform, 1 the [`BuildingRecord`]s (by draw
/// id), 2 the pyramid (unfilterable `texture_2d<f32>`, all levels), 3 the per-box status (`u32`),
/// 4 the appended [`DrawIndexedIndirectArgs`], 5 their count (atomic `u32`), 6 the [`CullPart`]s
/// the records name, 7 the drawn-early flags (`u32` per box), 8 the boxes' draw ids, 9 the
/// visibility stamps and 10 the parents (`u32` per draw id).
pub const HZB_CULL_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/hzb_cull.wgsl"));

/// Pyramid debug view (`wgsl/debug_pyramid.wgsl`): entry points `vs_main` (fullscreen
/// triangle, no buffers) and `fs_main`; group 0: binding 0 the [`PyramidViewParams`] uniform,
/// binding 1 one mip of the pyramid (unfilterable `texture_2d<f32>`).
pub const DEBUG_PYRAMID_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/debug_pyramid.wgsl"));

/// Cluster-colour debug view (`wgsl/debug_clusters.wgsl`): like [`SCENE_WGSL`] (group 0
/// binding 0 the [`ViewUniforms`], vertex buffer of [`SceneVertex`]) with a colour per draw id.
pub const DEBUG_CLUSTERS_WGSL: &str =
    include_str!(concat!(env!("OUT_DIR"), "/debug_clusters.wgsl"));

/// Occluder debug view (`wgsl/debug_occluders.wgsl`): like [`SCENE_WGSL`]; the instance index
/// picks the colour (0 an occluder, 1 a selected one); alpha-blended.
pub const DEBUG_OCCLUDERS_WGSL: &str =
    include_str!(concat!(env!("OUT_DIR"), "/debug_occluders.wgsl"));

/// Outline of a picked draw (`wgsl/outline.wgsl`): a line list of [`SceneVertex`] (the id gives
/// its [`depth_tie_factor`], as the faces it borders) in [`constants::OUTLINE_RGB`], pulled
/// towards the eye by [`constants::OUTLINE_DEPTH_BIAS_REL`]; group 0 binding 0 the
/// [`ViewUniforms`].
pub const OUTLINE_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/outline.wgsl"));

/// Cluster texture bake (`wgsl/bake.wgsl`): entry points `vs_main`, `fs_main`; group 0:
/// binding 0 the [`BakeView`]s of a batch of draws (storage; a draw's instance index picks
/// its view), binding 1 each building's top (`f32` per building id); vertex buffer of
/// [`SceneVertex`]; writes albedo.
pub const BAKE_WGSL: &str = include_str!(concat!(env!("OUT_DIR"), "/bake.wgsl"));

/// Every composed shader by file name, for tests that validate or inspect them all.
pub const ALL_WGSL: &[(&str, &str)] = &[
    ("scene.wgsl", SCENE_WGSL),
    ("ids.wgsl", IDS_WGSL),
    ("hzb_build.wgsl", HZB_BUILD_WGSL),
    ("hzb_cull.wgsl", HZB_CULL_WGSL),
    ("debug_pyramid.wgsl", DEBUG_PYRAMID_WGSL),
    ("debug_clusters.wgsl", DEBUG_CLUSTERS_WGSL),
    ("debug_occluders.wgsl", DEBUG_OCCLUDERS_WGSL),
    ("outline.wgsl", OUTLINE_WGSL),
    ("bake.wgsl", BAKE_WGSL),
];

#[cfg(test)]
mod tests {
    use super::constants::DEPTH_TIE_STEP_REL;
    use super::*;

    /// The tie level of building `id`: how many steps its depth is pushed.
    fn level(id: u32) -> usize {
        ((1.0 - f64::from(depth_tie_factor(id))) / f64::from(DEPTH_TIE_STEP_REL)).round() as usize
    }

    #[test]
    fn depth_tie_factors_push_farther_by_at_most_255_steps() {
        let largest = (255.0 * DEPTH_TIE_STEP_REL) as f64;
        for id in (0..1_000_000).step_by(7) {
            let f = depth_tie_factor(id) as f64;
            assert!(f <= 1.0 && f >= 1.0 - largest - 1e-12, "id {id}: {f}");
            // A whole number of steps below 1, exactly (the product is exact in f32).
            let steps = (1.0 - f) / DEPTH_TIE_STEP_REL as f64;
            assert_eq!(steps, steps.round(), "id {id}");
        }
        assert_eq!(depth_tie_factor(GROUND_ID), 1.0);
        assert_eq!(depth_tie_factor(SURFACE_ID_BASE + 3), 1.0);
    }

    #[test]
    fn neighbouring_ids_get_distinct_tie_levels() {
        // A building drawn twice in OSM is often two consecutive ids: Fibonacci hashing sends
        // ids up to 13 apart at least 8 levels apart, and spreads all of them evenly.
        for id in 0..100_000u32 {
            for gap in 1..14 {
                assert!(
                    level(id).abs_diff(level(id + gap)) >= 8,
                    "ids {id}, {}",
                    id + gap
                );
            }
        }
        let mut counts = [0u32; 256];
        for id in 0..256_000u32 {
            counts[level(id)] += 1;
        }
        assert!(
            counts.iter().all(|&c| (900..=1100).contains(&c)),
            "{counts:?}"
        );
    }
}
