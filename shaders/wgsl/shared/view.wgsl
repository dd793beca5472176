// Per-view uniforms shared by every pass that draws with the camera.
// Rust twin: citywalk_shaders::ViewUniforms.
struct View {
    // World (local frame, metres, z up) to clip space; reversed-Z infinite projection.
    view_proj: mat4x4<f32>,
    // Eye position in metres (w unused).
    camera_position_m: vec4<f32>,
    // Unit vector towards the sun (w unused).
    sun_direction: vec4<f32>,
    // Linear RGB of the sky; distance fog fades towards it (a = unused).
    sky_colour: vec4<f32>,
    // x: fog density per metre, y: viewport width px, z: viewport height px, w: the highlighted
    // draw id + 1 (0: none).
    params: vec4<f32>,
}

// One orthographic view of the cluster texture bake (Chang et al. 2008 §7).
// Rust twin: citywalk_shaders::BakeView.
struct BakeView {
    // World (local frame, metres) to clip space, the buildings already scaled; reversed Z.
    world_to_clip: mat4x4<f32>,
    // x: the cluster's roof height (m), to which every building is scaled; yzw unused.
    params: vec4<f32>,
}
