// Flat-shaded city: walls and roofs with per-building colour variation, a sun and ambient light,
// distance fog towards the sky colour, and the ground plane. Reversed Z (see engine camera.rs).

@group(0) @binding(0) var<uniform> view: View;

struct VertexOutput {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_m: vec3<f32>,
    @location(1) @interpolate(flat) building_id: u32,
}

@vertex
fn vs_main(v: SceneVertex) -> VertexOutput {
    var out: VertexOutput;
    out.clip = view.view_proj * vec4<f32>(v.position_m, 1.0);
    out.world_m = v.position_m;
    out.building_id = v.building_id;
    return out;
}

// Ground surfaces by layer (citywalk_scenes::ground_surfaces::SurfaceLayer::index): ground areas
// (other land, grass, forest, park, paved, water), then streets from minor to major (other,
// footway, service, residential, minor, major): asphalt darkens with the road's rank.
fn surface_colour(layer: u32) -> vec3<f32> {
    var palette = array<vec3<f32>, SURFACE_LAYER_COUNT>(
        vec3<f32>(0.62, 0.60, 0.52), // other land
        vec3<f32>(0.52, 0.64, 0.40), // grass
        vec3<f32>(0.30, 0.46, 0.28), // forest
        vec3<f32>(0.44, 0.62, 0.36), // park
        vec3<f32>(0.70, 0.69, 0.66), // paved square
        vec3<f32>(0.36, 0.53, 0.72), // water
        vec3<f32>(0.50, 0.50, 0.50), // other street
        vec3<f32>(0.74, 0.70, 0.64), // footway
        vec3<f32>(0.46, 0.46, 0.47), // service road
        vec3<f32>(0.42, 0.42, 0.44), // residential street
        vec3<f32>(0.39, 0.39, 0.41), // minor road
        vec3<f32>(0.35, 0.35, 0.37), // major road
    );
    return srgb_to_linear(palette[min(layer, SURFACE_LAYER_COUNT - 1u)]);
}

@fragment
fn fs_main(in: VertexOutput) -> @location(0) vec4<f32> {
    // Flat normal from screen-space derivatives, turned towards the eye (meshes from files may
    // have mixed winding; culling is off).
    var n = normalize(cross(dpdy(in.world_m), dpdx(in.world_m)));
    let to_eye = view.camera_position_m.xyz - in.world_m;
    if dot(n, to_eye) < 0.0 {
        n = -n;
    }
    var albedo: vec3<f32>;
    if in.building_id == GROUND_ID {
        // Bare ground between the streets and areas: a plain earth tone.
        albedo = bare_ground_colour();
        n = vec3<f32>(0.0, 0.0, 1.0);
    } else if in.building_id >= SURFACE_ID_BASE {
        albedo = surface_colour(in.building_id - SURFACE_ID_BASE);
        n = vec3<f32>(0.0, 0.0, 1.0);
    } else if n.z > 0.7 {
        albedo = roof_colour(in.building_id);
    } else {
        albedo = facade_colour(in.building_id);
    }
    // A picked building or cluster mesh: tinted amber (params.w: its draw id + 1, 0 for none).
    let highlight = u32(view.params.w);
    if highlight != 0u && in.building_id == highlight - 1u {
        albedo = mix(albedo, vec3<f32>(1.0, 0.45, 0.05), 0.6);
    }
    let sun = max(dot(n, view.sun_direction.xyz), 0.0);
    // Sky light: surfaces facing up see more of the sky.
    let sky = AMBIENT * (0.75 + 0.25 * n.z);
    var colour = albedo * (sky + (1.0 - AMBIENT) * sun);
    let distance_m = length(to_eye);
    let fog = 1.0 - exp(-view.params.x * distance_m);
    colour = mix(colour, view.sky_colour.rgb, clamp(fog, 0.0, 1.0));
    return vec4<f32>(colour, 1.0);
}
