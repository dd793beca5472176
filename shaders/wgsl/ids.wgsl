// The id pass: every pixel gets the id of the nearest building plus ID_OFFSET, or ID_BACKGROUND
// (0) where the ground or the sky is seen. Drawn without culling, reversed Z; read back by the
// visibility oracle (engine oracle.rs).

@group(0) @binding(0) var<uniform> view: View;

struct IdVertexOutput {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) building_id: u32,
}

@vertex
fn vs_main(v: SceneVertex) -> IdVertexOutput {
    var out: IdVertexOutput;
    out.clip = tie_broken_clip(view.view_proj * vec4<f32>(v.position_m, 1.0), v.building_id);
    out.building_id = v.building_id;
    return out;
}

@fragment
fn fs_main(in: IdVertexOutput) -> @location(0) u32 {
    if in.building_id == GROUND_ID {
        return ID_BACKGROUND;
    }
    return in.building_id + ID_OFFSET;
}
