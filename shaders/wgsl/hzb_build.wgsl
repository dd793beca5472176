// Hierarchical-Z pyramid build (engine `hzb::build`), the GPU twin of `hzb::reference`:
// reversed Z, each texel keeps the minimum (farthest) depth of the texels it covers.
//
// `copy_depth` writes levels 0 and 1 from the Depth32Float depth buffer, `merge_depths` from two
// of them with the nearer (greater, reversed Z) depth kept per texel: the frame's depth and its
// virtual occluders' depth, so that the occluders need no copy of the frame's depth to be drawn
// into. `reduce` then writes level l + 1 from level l, once per level from level 1. Level l + 1
// has ceil(w / 2) x ceil(h / 2) texels and texel (x, y) is the minimum of the texels 2x, 2x + 1
// (in each direction) of level l that exist, so an odd last row or column is never dropped.
//
// Texture mips halve with floor, the pyramid with ceil, so the texture is allocated at the next
// powers of two of the viewport and each level uses only its top-left logical region; the sizes
// of that region come as a uniform per level, and texels outside it are never written or read.
//
// Driver traps (shared/GPU-NOTES.md): the depth buffer is bound as `texture_2d<f32>` (unfilterable
// float) and read through `.r`, as GL cannot `textureLoad` a `texture_depth_2d`; the source level
// is a read-only storage texture, as GL loses writes to level l + 1 while level l is bound as a
// sampled view; every view is a single level, so no level index varies per invocation.

@group(0) @binding(0) var depth_in: texture_2d<f32>;
// `merge_depths` only: the second depth, merged into the first (bound to the first otherwise).
@group(0) @binding(5) var depth_merged: texture_2d<f32>;
@group(0) @binding(1) var level0_out: texture_storage_2d<r32float, write>;
// Level 1 (the texture has at least two mips even when the pyramid has one level).
@group(0) @binding(6) var level1_out: texture_storage_2d<r32float, write>;

@compute @workgroup_size(HZB_BUILD_WORKGROUP, HZB_BUILD_WORKGROUP, 1)
fn copy_depth(@builtin(global_invocation_id) id: vec3<u32>) {
    base_levels(id.xy, false);
}

@compute @workgroup_size(HZB_BUILD_WORKGROUP, HZB_BUILD_WORKGROUP, 1)
fn merge_depths(@builtin(global_invocation_id) id: vec3<u32>) {
    base_levels(id.xy, true);
}

// Level-1 texel `t`: the up to 2x2 level-0 texels under it (those inside the viewport) copied,
// and their minimum written to level 1.
fn base_levels(t: vec2<u32>, merged: bool) {
    let size = textureDimensions(depth_in);
    let base = t * 2u;
    if base.x >= size.x || base.y >= size.y {
        return;
    }
    var m = 1.0;
    for (var k = 0u; k < 4u; k++) {
        let p = base + vec2<u32>(k & 1u, k >> 1u);
        if p.x < size.x && p.y < size.y {
            var d = textureLoad(depth_in, vec2<i32>(p), 0).r;
            if merged {
                d = max(d, textureLoad(depth_merged, vec2<i32>(p), 0).r);
            }
            textureStore(level0_out, vec2<i32>(p), vec4<f32>(d, 0.0, 0.0, 1.0));
            m = min(m, d);
        }
    }
    textureStore(level1_out, vec2<i32>(t), vec4<f32>(m, 0.0, 0.0, 1.0));
}

@group(0) @binding(2) var level_src: texture_storage_2d<r32float, read>;
@group(0) @binding(3) var level_dst: texture_storage_2d<r32float, write>;
// xy: logical size of level l (the source), zw: of level l + 1 (the destination).
@group(0) @binding(4) var<uniform> level_sizes: vec4<u32>;

@compute @workgroup_size(HZB_BUILD_WORKGROUP, HZB_BUILD_WORKGROUP, 1)
fn reduce(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= level_sizes.z || id.y >= level_sizes.w {
        return;
    }
    let src_size = vec2<i32>(level_sizes.xy);
    let base = vec2<i32>(id.xy) * 2;
    // The texel (2x, 2y) always exists; the others only inside the source level.
    var m = textureLoad(level_src, base).r;
    let right = base.x + 1 < src_size.x;
    let below = base.y + 1 < src_size.y;
    if right {
        m = min(m, textureLoad(level_src, base + vec2<i32>(1, 0)).r);
    }
    if below {
        m = min(m, textureLoad(level_src, base + vec2<i32>(0, 1)).r);
    }
    if right && below {
        m = min(m, textureLoad(level_src, base + vec2<i32>(1, 1)).r);
    }
    textureStore(level_dst, vec2<i32>(id.xy), vec4<f32>(m, 0.0, 0.0, 1.0));
}
