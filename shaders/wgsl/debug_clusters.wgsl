// Debug view: every drawn building or cluster mesh in its own colour, as in Chang et al. 2008
// Fig. 1(c) (engine `render::debug::clusters`). The colour is a hash of the vertex's draw id
// (in a LOD scene: building ids, then cluster node n at building_count + n); roofs are drawn at
// full brightness, walls at DEBUG_WALL_SHADE, the ground dark grey.

@group(0) @binding(0) var<uniform> view: View;

struct VertexOutput {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_m: vec3<f32>,
    @location(1) @interpolate(flat) draw_id: u32,
}

@vertex
fn vs_main(v: SceneVertex) -> VertexOutput {
    var out: VertexOutput;
    out.clip = tie_broken_clip(view.view_proj * vec4<f32>(v.position_m, 1.0), v.building_id);
    out.world_m = v.position_m;
    out.draw_id = v.building_id;
    return out;
}

// HSV (all in [0, 1]) to RGB. Rust twin: engine `render::debug::clusters::hsv_to_rgb`.
fn hsv_to_rgb(h: f32, s: f32, v: f32) -> vec3<f32> {
    let k = (vec3<f32>(5.0, 3.0, 1.0) + h * 6.0) % 6.0;
    return v - v * s * clamp(min(k, 4.0 - k), vec3<f32>(0.0), vec3<f32>(1.0));
}

// The colour of draw id `id` (linear RGB). Rust twin: engine
// `render::debug::clusters::cluster_colour`.
fn cluster_colour(id: u32) -> vec3<f32> {
    let h = hash_u32(id);
    let hue = f32(h & 0xffffu) / 65536.0;
    let saturation = 0.55 + 0.45 * f32((h >> 16u) & 0xffu) / 255.0;
    let value = 0.65 + 0.35 * f32(h >> 24u) / 255.0;
    return hsv_to_rgb(hue, saturation, value);
}

@fragment
fn fs_main(in: VertexOutput) -> @location(0) vec4<f32> {
    if in.draw_id == GROUND_ID {
        return vec4<f32>(DEBUG_GROUND_GREY, DEBUG_GROUND_GREY, DEBUG_GROUND_GREY, 1.0);
    }
    var n = normalize(cross(dpdy(in.world_m), dpdx(in.world_m)));
    if dot(n, view.camera_position_m.xyz - in.world_m) < 0.0 {
        n = -n;
    }
    var shade = DEBUG_WALL_SHADE;
    if n.z > 0.7 {
        shade = 1.0;
    }
    return vec4<f32>(cluster_colour(in.draw_id) * shade, 1.0);
}
