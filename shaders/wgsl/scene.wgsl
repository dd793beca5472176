// Flat-shaded city: walls and roofs with per-building colour variation, a sun and ambient light,
// distance fog towards the sky colour, and the ground plane. Reversed Z (see engine camera.rs).

@group(0) @binding(0) var<uniform> view: View;

// The cluster textures (fs_textured only; see citywalk_shaders::SCENE_WGSL).
@group(1) @binding(0) var<uniform> texturing: ClusterTexturing;
@group(1) @binding(1) var<storage, read> textured_clusters: array<TexturedCluster>;
@group(1) @binding(2) var<storage, read> textured_walls: array<TexturedWall>;
// Per page view (page * TEXTURE_PAGE_VIEWS + view): its layer in `pages`, or NO_TEXTURE_PAGE.
@group(1) @binding(3) var<storage, read> page_layers: array<u32>;
@group(1) @binding(4) var pages: texture_2d_array<f32>;
@group(1) @binding(5) var page_sampler: sampler;

struct VertexOutput {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_m: vec3<f32>,
    @location(1) @interpolate(flat) building_id: u32,
    // The vertex buffer index of the triangle's first vertex (flat takes the first): on an
    // extruded cluster mesh, an even offset 2i from its base vertex is wall i's foot, an odd
    // one a roof corner (citywalk_scenes::extrude::extruded_walls).
    @location(2) @interpolate(flat) vertex_index: u32,
}

@vertex
fn vs_main(v: SceneVertex, @builtin(vertex_index) vertex_index: u32) -> VertexOutput {
    var out: VertexOutput;
    out.clip = tie_broken_clip(view.view_proj * vec4<f32>(v.position_m, 1.0), v.building_id);
    out.world_m = v.position_m;
    out.building_id = v.building_id;
    out.vertex_index = vertex_index;
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

// The surface normal from screen-space derivatives, turned towards the eye (meshes from files
// may have mixed winding; culling is off); straight up on the ground and its surfaces.
fn facing_normal(in: VertexOutput) -> vec3<f32> {
    var n = normalize(cross(dpdy(in.world_m), dpdx(in.world_m)));
    if dot(n, view.camera_position_m.xyz - in.world_m) < 0.0 {
        n = -n;
    }
    if in.building_id >= SURFACE_ID_BASE {
        n = vec3<f32>(0.0, 0.0, 1.0);
    }
    return n;
}

// The flat albedo of a fragment: the ground, its surfaces, roofs and facades.
fn flat_albedo(in: VertexOutput, n: vec3<f32>) -> vec3<f32> {
    if in.building_id == GROUND_ID {
        // Bare ground between the streets and areas: a plain earth tone.
        return bare_ground_colour();
    } else if in.building_id >= SURFACE_ID_BASE {
        return surface_colour(in.building_id - SURFACE_ID_BASE);
    } else if n.z > 0.7 {
        return roof_colour(in.building_id);
    }
    return facade_colour(in.building_id);
}

// Lights `albedo` (sun and sky), tints the picked draw and fades into the fog.
fn shade(in: VertexOutput, albedo_in: vec3<f32>, n: vec3<f32>) -> vec4<f32> {
    var albedo = albedo_in;
    // A picked building or cluster mesh: tinted amber (params.w: its draw id + 1, 0 for none).
    let highlight = u32(view.params.w);
    if highlight != 0u && in.building_id == highlight - 1u {
        albedo = mix(albedo, vec3<f32>(1.0, 0.45, 0.05), 0.6);
    }
    let sun = max(dot(n, view.sun_direction.xyz), 0.0);
    // Sky light: surfaces facing up see more of the sky.
    let sky = AMBIENT * (0.75 + 0.25 * n.z);
    var colour = albedo * (sky + (1.0 - AMBIENT) * sun);
    let distance_m = length(view.camera_position_m.xyz - in.world_m);
    let fog = 1.0 - exp(-view.params.x * distance_m);
    colour = mix(colour, view.sky_colour.rgb, clamp(fog, 0.0, 1.0));
    return vec4<f32>(colour, 1.0);
}

@fragment
fn fs_main(in: VertexOutput) -> @location(0) vec4<f32> {
    let n = facing_normal(in);
    return shade(in, flat_albedo(in, n), n);
}

// The baked albedo of a cluster mesh's fragment (Chang et al. 2008 §7: a wall samples its
// image in the side view, the roof this frame's roof view), or `flat` where the cluster has
// no textures or its page view is not resident yet.
fn cluster_albedo(in: VertexOutput, flat: vec3<f32>) -> vec3<f32> {
    let node = in.building_id - texturing.building_count;
    if node >= arrayLength(&textured_clusters) {
        return flat;
    }
    let cluster = textured_clusters[node];
    if cluster.page == NO_TEXTURE_PAGE {
        return flat;
    }
    let local = in.vertex_index - cluster.base_vertex;
    var texel: vec2<f32>;
    var view_index = 0u;
    if local % 2u == 0u {
        let wall = local / 2u;
        if wall >= cluster.wall_count {
            return flat;
        }
        let w = textured_walls[min(cluster.first_wall + wall, arrayLength(&textured_walls) - 1u)];
        texel = wall_texel(cluster, w, in.world_m);
    } else {
        view_index = texturing.roof_view;
        texel = roof_texel(cluster, texturing.roof_right.xyz, texturing.roof_down.xyz, in.world_m);
    }
    let slot = cluster.page * TEXTURE_PAGE_VIEWS + view_index;
    if slot >= arrayLength(&page_layers) {
        return flat;
    }
    let layer = page_layers[slot];
    if layer == NO_TEXTURE_PAGE {
        return flat;
    }
    return textureSampleLevel(pages, page_sampler, texel / texturing.page_px, layer, 0.0).rgb;
}

// The bins debug view: a textured cluster in its texture bin's colour, an untextured one dark.
fn bin_albedo(in: VertexOutput) -> vec3<f32> {
    let node = in.building_id - texturing.building_count;
    if node >= arrayLength(&textured_clusters) || textured_clusters[node].page == NO_TEXTURE_PAGE {
        return vec3<f32>(0.08);
    }
    let bin = u32(textured_clusters[node].box_lo_m.w);
    var palette = array<vec3<f32>, 8>(
        vec3<f32>(0.90, 0.10, 0.10),
        vec3<f32>(0.95, 0.55, 0.05),
        vec3<f32>(0.95, 0.90, 0.10),
        vec3<f32>(0.20, 0.80, 0.20),
        vec3<f32>(0.10, 0.75, 0.85),
        vec3<f32>(0.15, 0.30, 0.95),
        vec3<f32>(0.60, 0.20, 0.90),
        vec3<f32>(0.95, 0.40, 0.75),
    );
    // Bins past the eighth repeat the colours, darker.
    return palette[bin % 8u] * select(1.0, 0.45, bin >= 8u);
}

// fs_main with the cluster meshes' baked textures (group 1).
@fragment
fn fs_textured(in: VertexOutput) -> @location(0) vec4<f32> {
    let n = facing_normal(in);
    var albedo = flat_albedo(in, n);
    let cluster = in.building_id >= texturing.building_count && in.building_id < SURFACE_ID_BASE;
    if cluster && texturing.shading == CLUSTER_SHADING_TEXTURED {
        albedo = cluster_albedo(in, albedo);
    } else if cluster && texturing.shading == CLUSTER_SHADING_BINS {
        albedo = bin_albedo(in);
    }
    return shade(in, albedo, n);
}
