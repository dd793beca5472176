// Hierarchical-Z pyramid build (engine `hzb::build`), the GPU twin of `hzb::reference`:
// reversed Z, each texel keeps the minimum (farthest) depth of the texels it covers.
//
// `copy_depth` writes levels 0 and 1 from the Depth32Float depth buffer, `merge_depths` from two
// of them with the nearer (greater, reversed Z) depth kept per texel: the frame's depth and its
// virtual occluders' depth, so that the occluders need no copy of the frame's depth to be drawn
// into; the occluders' depth is eroded first (`base_levels`), as by `copy_eroded`, which reads
// the occluder gate's depth alone. `reduce` then writes level l + 1 from level l, once per level from level 1. Level l + 1
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
// `merge_depths`: the occluders' depth, merged into the first; `copy_eroded`: the only depth
// read (bound to the first otherwise).
@group(0) @binding(5) var depth_merged: texture_2d<f32>;
@group(0) @binding(1) var level0_out: texture_storage_2d<r32float, write>;
// Level 1 (the texture has at least two mips even when the pyramid has one level).
@group(0) @binding(6) var level1_out: texture_storage_2d<r32float, write>;

// How the first dispatch reads its depth.
const PLAIN: u32 = 0u;
// Only `depth_merged`, eroded: the occluder gate's culling depth (the ground and occluders).
const ERODED: u32 = 1u;
// `depth_in` with `depth_merged` eroded, the nearer kept: the early depth and the occluders'.
const MERGED: u32 = 2u;

@compute @workgroup_size(HZB_BUILD_WORKGROUP, HZB_BUILD_WORKGROUP, 1)
fn copy_depth(@builtin(global_invocation_id) id: vec3<u32>) {
    base_levels(id.xy, PLAIN);
}

@compute @workgroup_size(HZB_BUILD_WORKGROUP, HZB_BUILD_WORKGROUP, 1)
fn copy_eroded(@builtin(global_invocation_id) id: vec3<u32>) {
    base_levels(id.xy, ERODED);
}

@compute @workgroup_size(HZB_BUILD_WORKGROUP, HZB_BUILD_WORKGROUP, 1)
fn merge_depths(@builtin(global_invocation_id) id: vec3<u32>) {
    base_levels(id.xy, MERGED);
}

// Level-1 texel `t`: the up to 2x2 level-0 texels under it (those inside the viewport) written,
// and their minimum written to level 1.
//
// Erosion (engine `hzb::reference::erode`): a texel of the virtual occluders' depth counts as
// the farthest of itself and its four edge neighbours, texels outside the viewport as cleared.
// An occluder lies inside its building, but where its edge meets the building's silhouette the
// two are rasterised by different draws, and the occluder can cover a pixel centre a hundredth
// of a pixel outside the building (seen on a generated city of 1M buildings). Such a pixel is
// within a fraction of a pixel of the occluder's edge, so the neighbour across that edge along
// the edge normal's larger axis (at least 0.7 px across) is uncovered or farther.
fn base_levels(t: vec2<u32>, mode: u32) {
    let size = textureDimensions(depth_in);
    let base = t * 2u;
    if base.x >= size.x || base.y >= size.y {
        return;
    }
    // The second depth at base - 1 .. base + 2 (4x4 but its corners, which no texel's
    // neighbourhood reaches), 0 outside the viewport.
    var window: array<f32, 16>;
    if mode != PLAIN {
        for (var k = 0u; k < 16u; k++) {
            if k == 0u || k == 3u || k == 12u || k == 15u {
                continue;
            }
            let q = vec2<i32>(base) + vec2<i32>(i32(k & 3u), i32(k >> 2u)) - vec2<i32>(1, 1);
            var v = 0.0;
            if q.x >= 0 && q.y >= 0 && u32(q.x) < size.x && u32(q.y) < size.y {
                v = textureLoad(depth_merged, q, 0).r;
            }
            window[k] = v;
        }
    }
    var m = 1.0;
    for (var k = 0u; k < 4u; k++) {
        let o = vec2<u32>(k & 1u, k >> 1u);
        let p = base + o;
        if p.x < size.x && p.y < size.y {
            var d = 0.0;
            if mode != ERODED {
                d = textureLoad(depth_in, vec2<i32>(p), 0).r;
            }
            if mode != PLAIN {
                // The texel and its four edge neighbours (window origin: base - 1).
                let c = (o.y + 1u) * 4u + o.x + 1u;
                let e = min(
                    min(window[c], window[c - 1u]),
                    min(min(window[c + 1u], window[c - 4u]), window[c + 4u]),
                );
                d = max(d, e);
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
