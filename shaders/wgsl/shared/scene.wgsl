// The scene's geometry as the GPU sees it.

// One vertex of the city's vertex buffer (16 bytes).
// Rust twin: citywalk_shaders::SceneVertex.
struct SceneVertex {
    @location(0) position_m: vec3<f32>,
    // Building id, or GROUND_ID for the ground plane.
    @location(1) building_id: u32,
}

// Per-building record in a storage buffer: bounds and the index range of its triangles.
// Rust twin: citywalk_shaders::BuildingRecord.
struct BuildingRecord {
    bounds_min_m: vec3<f32>,
    first_index: u32,
    bounds_max_m: vec3<f32>,
    index_count: u32,
    base_vertex: i32,
    vertex_count: u32,
    // Parts first_part.. of the CullPart buffer (0 parts: the bounds alone).
    first_part: u32,
    part_count: u32,
}

// One part of a building's cull bounds: a prism over the convex quadrilateral of four (x, y)
// corners (corners_xy[0].xy, [0].zw, [1].xy, [1].zw), from z_min_m to z_max_m.
// Rust twin: citywalk_shaders::CullPart.
struct CullPart {
    corners_xy: array<vec4<f32>, 2>,
    z_min_m: f32,
    z_max_m: f32,
    _pad0: u32,
    _pad1: u32,
}

// Arguments of one indexed indirect draw, as wgpu reads them.
// Rust twin: citywalk_shaders::DrawIndexedIndirectArgs.
struct DrawIndexedIndirectArgs {
    index_count: u32,
    instance_count: u32,
    first_index: u32,
    base_vertex: i32,
    first_instance: u32,
}

// The clip position `clip` of a vertex of building `id`, its depth pushed farther by the
// building's own factor (Rust twin: citywalk_shaders::depth_tie_factor). Coplanar faces of two
// buildings (overlapping footprints in OSM) tie in the depth test, and a tie goes to whichever
// is drawn first: an order that culling changes from frame to frame (the early and late passes,
// the GPU's compaction), so such faces flickered and no two modes agreed. With a factor per
// building the same one wins in every order. Farther only, and an occluder carries its
// building's id and moves with it, staying behind its building's faces: a depth pyramid of
// these depths hides only what they hide. The ground and its surfaces keep their depth.
fn tie_broken_clip(clip: vec4<f32>, id: u32) -> vec4<f32> {
    if id == GROUND_ID || id >= SURFACE_ID_BASE {
        return clip;
    }
    let level = (id * FIBONACCI_HASH) >> (32u - DEPTH_TIE_BITS);
    return vec4<f32>(clip.xy, clip.z * (1.0 - f32(level) * DEPTH_TIE_STEP_REL), clip.w);
}
