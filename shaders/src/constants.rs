// Constants shared by Rust and WGSL, defined once here. `build.rs` `include!`s this file and
// emits every entry of `WGSL_U32` / `WGSL_F32` as a WGSL `const` at the top of each composed
// shader, so the values are never typed twice. (Plain `//` comments: this file is also included
// by the build script, where inner doc comments are not allowed.)

/// `building_id` of the ground plane's vertices: not a building. The id pass writes 0 for it.
pub const GROUND_ID: u32 = u32::MAX;

/// `building_id` of the first ground-surface layer (streets, water, parks): a surface of layer
/// `k` (`citywalk_scenes::ground_surfaces::SurfaceLayer::index`) has `SURFACE_ID_BASE + k`. Not a
/// building; drawn by the ground-surface pass only.
pub const SURFACE_ID_BASE: u32 = GROUND_ID - 64;

/// Ground-surface layers (`citywalk_scenes::ground_surfaces::SurfaceLayer::COUNT`, which asserts
/// it): the size of the shader's colour table. At most the 64 ids above [`SURFACE_ID_BASE`].
pub const SURFACE_LAYER_COUNT: u32 = 12;
const _: () = assert!(SURFACE_LAYER_COUNT <= GROUND_ID - SURFACE_ID_BASE);

/// Value of an id-buffer pixel that shows no building (sky or ground). A building with id `i`
/// writes `i + ID_OFFSET`.
pub const ID_BACKGROUND: u32 = 0;

/// What the id pass adds to a building id, so that 0 stays free for the background.
pub const ID_OFFSET: u32 = 1;

/// A cluster mesh without baked textures, or a texture page view not resident on the GPU
/// (the cluster texture tables of `wgsl/shared/cluster_textures.wgsl`).
pub const NO_TEXTURE_PAGE: u32 = u32::MAX;

/// How the textured scene pass shades cluster meshes: flat colours, baked textures, or each
/// textured cluster in the colour of its texture bin (the viewer's bins debug view; an
/// untextured cluster dark grey).
pub const CLUSTER_SHADING_FLAT: u32 = 0;
pub const CLUSTER_SHADING_TEXTURED: u32 = 1;
pub const CLUSTER_SHADING_BINS: u32 = 2;

/// Views of every cluster texture page (`citywalk_scenes::cluster_texture::AtlasView::ALL`,
/// which asserts it): the side view, then the five roof views.
pub const TEXTURE_PAGE_VIEWS: u32 = 6;

/// Ambient share of the flat-shaded scene colour (the rest is the sun's Lambert term).
pub const AMBIENT: f32 = 0.38;

/// The bare ground between streets and areas (sRGB): the scene pass's earth tone, and what the
/// cluster texture bake shows where no building is seen.
pub const BARE_GROUND_SRGB: [f32; 3] = [0.56, 0.56, 0.50];

// ---- Hierarchical-Z pyramid build and occlusion cull (engine `hzb::build`, `hzb::cull`). ----

/// Side of the square workgroup of the pyramid build (`wgsl/hzb_build.wgsl`).
pub const HZB_BUILD_WORKGROUP: u32 = 8;

/// Workgroup size of the cull pass (`wgsl/hzb_cull.wgsl`), one invocation per box.
pub const HZB_CULL_WORKGROUP: u32 = 64;

/// Cull status of a box that may be visible (drawn).
pub const CULL_VISIBLE: u32 = 0;

/// Cull status of a box entirely outside the view frustum (or behind the camera).
pub const CULL_FRUSTUM_OUTSIDE: u32 = 1;

/// Cull status of a box hidden behind the depth pyramid.
pub const CULL_OCCLUDED: u32 = 2;

/// Status the early entry points (`early`, `gate`) give a candidate that was not visible last
/// frame (or lies outside the frustum): not a candidate of the early pass.
pub const CULL_NOT_EARLY: u32 = 3;

/// [`HzbCullParams::flags`](crate::HzbCullParams) bit: the boxes' draw ids are bound.
pub const CULL_FLAG_DRAW_IDS: u32 = 1;

/// [`HzbCullParams::flags`](crate::HzbCullParams) bit: the visibility stamps and the parents of
/// the draw ids are bound.
pub const CULL_FLAG_VISIBILITY: u32 = 2;

/// Candidate frame's cull report (`wgsl/hzb_cull.wgsl`, binding 23), header words: candidates
/// the cull found occluded. Those outside the frustum are the rest: every candidate gets one of
/// three statuses, so the GPU counts only the two small groups and never touches a word per
/// culled candidate on the CPU's side.
pub const CULL_R_OCCLUDED: u32 = 0;

/// Cull report: candidates visible last frame that the occluder gate kept out.
pub const CULL_R_GATE_CULLED: u32 = 1;

/// Cull report: length of the kept list (candidates the cull found visible).
pub const CULL_R_KEPT: u32 = 2;

/// Cull report: length of the early list (candidates the early pass drew).
pub const CULL_R_EARLY: u32 = 3;

/// Cull report: header words before the kept list; the early list follows the kept list, each
/// with room for every candidate the buffer was sized for.
pub const CULL_R_WORDS: u32 = 4;

/// Parent of a draw id with none (a root, or a building of a scene without a cluster tree).
pub const NO_PARENT: u32 = u32::MAX;

/// A box corner whose clip-space `w` is at most this is behind the eye (`hzb::reference`).
pub const HZB_BEHIND_W: f32 = 1e-6;

/// Relative rounding allowance of the GPU cull: each clip coordinate may differ from the CPU
/// reference's by this times the sum of the magnitudes of its terms (about 17 ulp, several times
/// the worst case of a 4-term dot product on either side), and the GPU widens every comparison by
/// it in the visible direction.
pub const HZB_ROUNDING_REL: f32 = 2e-6;

/// Texels per side of the fine occlusion test: a box's screen rectangle is tested against the
/// finest pyramid level at which it spans at most this many texels each way (at most 16 × 16
/// reads, after a 2 × 2 test at the coarse level has not culled it). Ours, measured on the
/// generated 10k city's street walk against the full-scene depth: the 2 × 2 test alone kept
/// 2.5 × what an exact per-pixel rectangle test keeps (267 vs 95 boxes), a 16 × 16 read within
/// about 10 % of it (105); more reads cost cull time for little gain.
pub const HZB_FINE_SPAN: u32 = 16;

// ---- Debug views (engine `render::debug`, `wgsl/debug_*.wgsl`). ----

/// Brightness of walls (against roofs at 1) in the cluster and occluder debug views.
pub const DEBUG_WALL_SHADE: f32 = 0.7;

/// Linear grey of the ground in the cluster debug view.
pub const DEBUG_GROUND_GREY: f32 = 0.12;

/// Linear RGB of an occluder in the occluder debug view (blue).
pub const DEBUG_OCCLUDER_RGB: [f32; 3] = [0.15, 0.45, 1.0];

/// Linear RGB of an occluder the frame's pre-pass selected (orange).
pub const DEBUG_OCCLUDER_SELECTED_RGB: [f32; 3] = [1.0, 0.45, 0.05];

/// Opacity of the occluders blended over the frame.
pub const DEBUG_OCCLUDER_ALPHA: f32 = 0.6;

/// Tree cull (engine `hzb::tree_cull`): the LOD criterion of `TreeCullParams::criterion`.
pub const TREE_CRITERION_CHANG: u32 = 0;
pub const TREE_CRITERION_YANG: u32 = 1;
pub const TREE_CRITERION_GEOMETRIC: u32 = 2;

/// Tree cull: what the early entry point does with last frame's kept draw ids.
pub const TREE_EARLY_NONE: u32 = 0;
pub const TREE_EARLY_FRUSTUM: u32 = 1;

/// Tree cull: the deepest tree it walks (levels below the root, plus one).
pub const TREE_MAX_LEVELS: u32 = 64;

/// Tree cull: word indices of its counters buffer. The level being walked; draws appended
/// by the early entry and by the levels (the indirect draw counts); entries of the early list;
/// buildings culled by the frustum and by occlusion (whole subtrees); overflow (a queue or list
/// ran out: the frame is incomplete, an error); nodes visited; last frame's kept entries the
/// early entry reads; per level, queue entries and the first entry.
pub const TREE_C_LEVEL: u32 = 8;
pub const TREE_C_EARLY_DRAWS: u32 = 9;
pub const TREE_C_LATE_DRAWS: u32 = 10;
pub const TREE_C_EARLY_LISTED: u32 = 11;
pub const TREE_C_FRUSTUM_CULLED: u32 = 12;
pub const TREE_C_OCCLUSION_CULLED: u32 = 13;
pub const TREE_C_OVERFLOW: u32 = 14;
pub const TREE_C_VISITED: u32 = 16;
/// Tree cull: entries of last frame's kept list the early entry point reads (0 without an early
/// set).
pub const TREE_C_LAST_KEPT: u32 = 17;
/// Tree cull: workgroups of the current level dispatch that have finished (the last one moves
/// the walk to the next level).
pub const TREE_C_DONE: u32 = 18;
pub const TREE_C_QUEUE_LEN: u32 = 32;
pub const TREE_C_QUEUE_START: u32 = TREE_C_QUEUE_LEN + TREE_MAX_LEVELS;
pub const TREE_C_WORDS: u32 = TREE_C_QUEUE_START + TREE_MAX_LEVELS;

/// Tree cull: the kept lists' header words (the two halves' counts, then padding) before the
/// halves.
pub const TREE_LIST_HEADER: u32 = 4;

// ---- The outline of a picked building or cluster mesh (engine `render::outline`). ----

/// Linear RGB of the outline: a saturated yellow, apart from the amber tint of the picked draw
/// it rims, the sky behind it and every facade colour.
pub const OUTLINE_RGB: [f32; 3] = [1.0, 0.92, 0.02];

/// How far the outline's lines are pulled towards the eye, relative: their reversed-Z depth is
/// scaled by `1 + OUTLINE_DEPTH_BIAS_REL`, the depth of a point `1 / (1 + bias)` as far (0.3 %
/// of the distance). The lines lie on the faces they border and would otherwise tie with them
/// in the depth test; a relative bias holds at every distance, where a constant one in depth
/// units would be metres far away and nothing close by.
pub const OUTLINE_DEPTH_BIAS_REL: f32 = 0.003;

// ---- The depth tie rule of coplanar buildings (`wgsl/shared/scene.wgsl` `tie_broken_clip`). ----

/// Bits of a building's depth tie level: its reversed-Z depth is scaled by
/// `1 - level * DEPTH_TIE_STEP_REL`, `level` in `0..2^DEPTH_TIE_BITS` from its id
/// ([`depth_tie_factor`]). Two buildings share a level with odds of one in 256.
pub const DEPTH_TIE_BITS: u32 = 8;

/// One tie level, relative: 2^-21, eight units in the last place of a depth in [0.5, 1), above
/// the rounding by which two rasterised triangles of one plane differ. The largest push is
/// 255 steps, 1.2e-4 of the distance (1.2 cm at 100 m): less than a pixel wherever two
/// buildings do not overlap.
pub const DEPTH_TIE_STEP_REL: f32 = 1.0 / (1u32 << 21) as f32;

/// The factor by which building `id`'s reversed-Z depth is scaled, in `(1 - 2^-13, 1]`
/// (Fibonacci hashing: consecutive ids land far apart). Twin of `tie_broken_clip` in
/// `wgsl/shared/scene.wgsl`; the ground and its surfaces keep their depth (factor 1).
pub const fn depth_tie_factor(id: u32) -> f32 {
    if id == GROUND_ID || id >= SURFACE_ID_BASE {
        return 1.0;
    }
    let level = id.wrapping_mul(FIBONACCI_HASH) >> (32 - DEPTH_TIE_BITS);
    1.0 - level as f32 * DEPTH_TIE_STEP_REL
}

/// 2^32 divided by the golden ratio, odd: the multiplier of Fibonacci hashing.
pub const FIBONACCI_HASH: u32 = 2_654_435_769;

/// Every `u32` constant emitted into WGSL, by name.
pub const WGSL_U32: &[(&str, u32)] = &[
    ("GROUND_ID", GROUND_ID),
    ("SURFACE_ID_BASE", SURFACE_ID_BASE),
    ("SURFACE_LAYER_COUNT", SURFACE_LAYER_COUNT),
    ("ID_BACKGROUND", ID_BACKGROUND),
    ("ID_OFFSET", ID_OFFSET),
    ("NO_TEXTURE_PAGE", NO_TEXTURE_PAGE),
    ("TEXTURE_PAGE_VIEWS", TEXTURE_PAGE_VIEWS),
    ("CLUSTER_SHADING_FLAT", CLUSTER_SHADING_FLAT),
    ("CLUSTER_SHADING_TEXTURED", CLUSTER_SHADING_TEXTURED),
    ("CLUSTER_SHADING_BINS", CLUSTER_SHADING_BINS),
    ("HZB_BUILD_WORKGROUP", HZB_BUILD_WORKGROUP),
    ("HZB_CULL_WORKGROUP", HZB_CULL_WORKGROUP),
    ("CULL_VISIBLE", CULL_VISIBLE),
    ("CULL_FRUSTUM_OUTSIDE", CULL_FRUSTUM_OUTSIDE),
    ("CULL_OCCLUDED", CULL_OCCLUDED),
    ("CULL_NOT_EARLY", CULL_NOT_EARLY),
    ("CULL_FLAG_DRAW_IDS", CULL_FLAG_DRAW_IDS),
    ("CULL_FLAG_VISIBILITY", CULL_FLAG_VISIBILITY),
    ("CULL_R_OCCLUDED", CULL_R_OCCLUDED),
    ("CULL_R_GATE_CULLED", CULL_R_GATE_CULLED),
    ("CULL_R_KEPT", CULL_R_KEPT),
    ("CULL_R_EARLY", CULL_R_EARLY),
    ("CULL_R_WORDS", CULL_R_WORDS),
    ("NO_PARENT", NO_PARENT),
    ("HZB_FINE_SPAN", HZB_FINE_SPAN),
    ("TREE_CRITERION_CHANG", TREE_CRITERION_CHANG),
    ("TREE_CRITERION_YANG", TREE_CRITERION_YANG),
    ("TREE_CRITERION_GEOMETRIC", TREE_CRITERION_GEOMETRIC),
    ("TREE_EARLY_NONE", TREE_EARLY_NONE),
    ("TREE_EARLY_FRUSTUM", TREE_EARLY_FRUSTUM),
    ("TREE_MAX_LEVELS", TREE_MAX_LEVELS),
    ("TREE_C_DONE", TREE_C_DONE),
    ("TREE_C_LEVEL", TREE_C_LEVEL),
    ("TREE_C_EARLY_DRAWS", TREE_C_EARLY_DRAWS),
    ("TREE_C_LATE_DRAWS", TREE_C_LATE_DRAWS),
    ("TREE_C_EARLY_LISTED", TREE_C_EARLY_LISTED),
    ("TREE_C_FRUSTUM_CULLED", TREE_C_FRUSTUM_CULLED),
    ("TREE_C_OCCLUSION_CULLED", TREE_C_OCCLUSION_CULLED),
    ("TREE_C_OVERFLOW", TREE_C_OVERFLOW),
    ("TREE_C_VISITED", TREE_C_VISITED),
    ("TREE_C_LAST_KEPT", TREE_C_LAST_KEPT),
    ("TREE_C_QUEUE_LEN", TREE_C_QUEUE_LEN),
    ("TREE_C_QUEUE_START", TREE_C_QUEUE_START),
    ("TREE_C_WORDS", TREE_C_WORDS),
    ("TREE_LIST_HEADER", TREE_LIST_HEADER),
    ("DEPTH_TIE_BITS", DEPTH_TIE_BITS),
    ("FIBONACCI_HASH", FIBONACCI_HASH),
];

/// Every `f32` constant emitted into WGSL, by name.
pub const WGSL_F32: &[(&str, f32)] = &[
    ("AMBIENT", AMBIENT),
    ("BARE_GROUND_SRGB_R", BARE_GROUND_SRGB[0]),
    ("BARE_GROUND_SRGB_G", BARE_GROUND_SRGB[1]),
    ("BARE_GROUND_SRGB_B", BARE_GROUND_SRGB[2]),
    ("HZB_BEHIND_W", HZB_BEHIND_W),
    ("HZB_ROUNDING_REL", HZB_ROUNDING_REL),
    ("DEBUG_WALL_SHADE", DEBUG_WALL_SHADE),
    ("DEBUG_GROUND_GREY", DEBUG_GROUND_GREY),
    ("DEBUG_OCCLUDER_R", DEBUG_OCCLUDER_RGB[0]),
    ("DEBUG_OCCLUDER_G", DEBUG_OCCLUDER_RGB[1]),
    ("DEBUG_OCCLUDER_B", DEBUG_OCCLUDER_RGB[2]),
    ("DEBUG_OCCLUDER_SELECTED_R", DEBUG_OCCLUDER_SELECTED_RGB[0]),
    ("DEBUG_OCCLUDER_SELECTED_G", DEBUG_OCCLUDER_SELECTED_RGB[1]),
    ("DEBUG_OCCLUDER_SELECTED_B", DEBUG_OCCLUDER_SELECTED_RGB[2]),
    ("DEBUG_OCCLUDER_ALPHA", DEBUG_OCCLUDER_ALPHA),
    ("OUTLINE_R", OUTLINE_RGB[0]),
    ("OUTLINE_G", OUTLINE_RGB[1]),
    ("OUTLINE_B", OUTLINE_RGB[2]),
    ("OUTLINE_DEPTH_BIAS_REL", OUTLINE_DEPTH_BIAS_REL),
    ("DEPTH_TIE_STEP_REL", DEPTH_TIE_STEP_REL),
];
