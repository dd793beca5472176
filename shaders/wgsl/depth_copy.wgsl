// Copies a reversed-Z Depth32Float texture into the bound depth attachment, texel for texel
// (engine `frame`: the depth the virtual occluders are added to before the pyramid is built).
//
// A fullscreen triangle writes `frag_depth` from the source (depth compare Always). Used instead
// of a texture-to-texture copy, which returned wrong depth on the GL backend (llvmpipe). The
// source is bound as an unfilterable `texture_2d<f32>` and read through `.r` (GL trap 2 of
// shared/GPU-NOTES.md).

@group(0) @binding(0) var source: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) p: vec4<f32>) -> @builtin(frag_depth) f32 {
    return textureLoad(source, vec2<i32>(p.xy), 0).r;
}
