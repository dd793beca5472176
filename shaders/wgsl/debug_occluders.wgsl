// Debug view: the virtual occluder meshes blended over the frame (engine
// `render::debug::occluders`). Instance 0 draws an occluder in DEBUG_OCCLUDER_COLOUR, instance 1
// in DEBUG_OCCLUDER_SELECTED_COLOUR (the occluders this frame's pre-pass selected), both with
// alpha DEBUG_OCCLUDER_ALPHA; walls are shaded by DEBUG_WALL_SHADE.

@group(0) @binding(0) var<uniform> view: View;

struct VertexOutput {
    // Invariant: the blend pass tests depth Equal against the depth-only pass.
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) world_m: vec3<f32>,
    @location(1) @interpolate(flat) selected: u32,
}

@vertex
fn vs_main(v: SceneVertex, @builtin(instance_index) instance: u32) -> VertexOutput {
    var out: VertexOutput;
    out.clip = view.view_proj * vec4<f32>(v.position_m, 1.0);
    out.world_m = v.position_m;
    out.selected = instance;
    return out;
}

@fragment
fn fs_main(in: VertexOutput) -> @location(0) vec4<f32> {
    var n = normalize(cross(dpdy(in.world_m), dpdx(in.world_m)));
    if dot(n, view.camera_position_m.xyz - in.world_m) < 0.0 {
        n = -n;
    }
    var shade = DEBUG_WALL_SHADE;
    if n.z > 0.7 {
        shade = 1.0;
    }
    var colour = vec3<f32>(DEBUG_OCCLUDER_R, DEBUG_OCCLUDER_G, DEBUG_OCCLUDER_B);
    if in.selected != 0u {
        colour = vec3<f32>(DEBUG_OCCLUDER_SELECTED_R, DEBUG_OCCLUDER_SELECTED_G,
            DEBUG_OCCLUDER_SELECTED_B);
    }
    return vec4<f32>(colour * shade, DEBUG_OCCLUDER_ALPHA);
}
