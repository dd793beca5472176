// The outline of a picked building or cluster mesh (engine `render::outline`): its feature
// edges as a line list, drawn after the frame against the frame's depth, so the edges the user
// sees show and the ones behind other surfaces do not. Reversed Z: nearer is larger.

@group(0) @binding(0) var<uniform> view: View;

@vertex
fn vs_main(v: SceneVertex) -> @builtin(position) vec4<f32> {
    var clip = tie_broken_clip(view.view_proj * vec4<f32>(v.position_m, 1.0), v.building_id);
    // Towards the eye, so a line wins the depth test against the faces it borders; never past
    // the near plane (depth 1).
    clip.z = min(clip.z * (1.0 + OUTLINE_DEPTH_BIAS_REL), clip.w);
    return clip;
}

@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return vec4<f32>(OUTLINE_R, OUTLINE_G, OUTLINE_B, 1.0);
}
