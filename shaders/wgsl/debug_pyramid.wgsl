// Debug view: one level of the hierarchical-Z pyramid as a greyscale full-screen image
// (engine `render::debug::pyramid`). `white_m` and nearer is white, `black_m` and farther black,
// the sky (reversed-Z depth 0) black; grey falls with the logarithm of the distance in between.
// On an sRGB target the grey is decoded first, so that the screen shows it as computed.
//
// The pyramid texture is padded to powers of two and level K is the top-left region of mip K
// (engine `hzb::build`): a single-level view of mip K is bound, so no level index is a shader
// value (trap 1 of shared/GPU-NOTES.md). Screen pixel p reads texel p >> K (pyramid levels
// halve with ceil, so texel t of level K covers pixels [t·2^K, (t+1)·2^K)).

// Rust twin: citywalk_shaders::PyramidViewParams.
struct PyramidViewParams {
    // Pyramid level shown.
    level: u32,
    // Logical size of that level in texels.
    level_width: u32,
    level_height: u32,
    // 1 when the target is sRGB-encoded.
    srgb_target: u32,
    // Near plane (m): reversed-Z depth d lies at distance near_m / d.
    near_m: f32,
    // Distances drawn white and black (m).
    white_m: f32,
    black_m: f32,
    _pad: f32,
}

@group(0) @binding(0) var<uniform> params: PyramidViewParams;
// Mip `level` of the R32Float pyramid, bound as unfilterable float.
@group(0) @binding(1) var level_texture: texture_2d<f32>;

@vertex
fn vs_main(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

// Grey level of a reversed-Z depth. Rust twin: engine `render::debug::pyramid::pyramid_grey`.
fn pyramid_grey(depth: f32, near_m: f32, white_m: f32, black_m: f32) -> f32 {
    if depth <= 0.0 {
        return 0.0;
    }
    let distance_m = near_m / depth;
    let t = log(distance_m / white_m) / log(black_m / white_m);
    return 1.0 - clamp(t, 0.0, 1.0);
}

@fragment
fn fs_main(@builtin(position) p: vec4<f32>) -> @location(0) vec4<f32> {
    let last = vec2<u32>(max(params.level_width, 1u) - 1u, max(params.level_height, 1u) - 1u);
    let texel = min(vec2<u32>(p.xy) >> vec2<u32>(params.level), last);
    let depth = textureLoad(level_texture, vec2<i32>(texel), 0).r;
    var g = pyramid_grey(depth, params.near_m, params.white_m, params.black_m);
    if params.srgb_target != 0u {
        g = pow(g, 2.2);
    }
    return vec4<f32>(g, g, g, 1.0);
}
