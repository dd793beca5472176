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
