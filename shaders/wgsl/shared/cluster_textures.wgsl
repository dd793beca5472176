// Where the baked textures of the cluster meshes lie (Chang et al. 2008 §7), and the texture
// coordinates of a point on a cluster mesh: the runtime half of citywalk_scenes'
// cluster_texture::atlas (SideLayout::uv, ClusterPlacement::roof_uv), which the bake rendered
// by.

// Per cluster tree node. Rust twin: citywalk_shaders::TexturedCluster.
struct TexturedCluster {
    // The mesh's first vertex in the scene's vertex buffer.
    base_vertex: u32,
    // Its walls: first_wall .. first_wall + wall_count of the wall table.
    first_wall: u32,
    wall_count: u32,
    // The page of its cells, or NO_TEXTURE_PAGE (flat colours).
    page: u32,
    // The roof views' image in the page: x, y, width, height (texels).
    roof_rect_px: vec4<f32>,
    // The box the roof views see (box_lo_m.w: the cluster's texture bin; box_hi_m.w unused).
    box_lo_m: vec4<f32>,
    box_hi_m: vec4<f32>,
}

// One wall of a textured cluster mesh. Rust twin: citywalk_shaders::TexturedWall.
struct TexturedWall {
    // The wall's first hull vertex (m).
    start_m: vec2<f32>,
    // Direction / length: dot(p - start, along) runs 0..1 along the wall.
    along_per_m: vec2<f32>,
    // Its image in the page's side view: x, y, width, height (texels; row 0 the wall's top).
    rect_px: vec4<f32>,
}

// Rust twin: citywalk_shaders::ClusterTexturingParams.
struct ClusterTexturing {
    // This frame's roof view (closest to the look vector): its image's right and down axes.
    roof_right: vec4<f32>,
    roof_down: vec4<f32>,
    page_px: f32,
    // Draw ids from here on are cluster nodes.
    building_count: u32,
    // The roof view's index among a page's TEXTURE_PAGE_VIEWS views.
    roof_view: u32,
    // CLUSTER_SHADING_FLAT, _TEXTURED or _BINS.
    shading: u32,
}

// The side-view texel (continuous, in the page) of the point `p` on wall `wall` of `cluster`:
// `along` from the wall's first vertex, `up` from the walls' foot to the roof.
fn wall_texel(cluster: TexturedCluster, wall: TexturedWall, p: vec3<f32>) -> vec2<f32> {
    let along = clamp(dot(p.xy - wall.start_m, wall.along_per_m), 0.0, 1.0);
    let height = cluster.box_hi_m.z - cluster.box_lo_m.z;
    let up = clamp((p.z - cluster.box_lo_m.z) / max(height, 1e-6), 0.0, 1.0);
    return wall.rect_px.xy + vec2<f32>(along, 1.0 - up) * wall.rect_px.zw;
}

// Where the box `lo`..`hi` projects along `axis`, as (min, max): roof_views::RoofView::frame.
fn box_range(lo: vec3<f32>, hi: vec3<f32>, axis: vec3<f32>) -> vec2<f32> {
    let a = lo * axis;
    let b = hi * axis;
    let low = min(a, b);
    let high = max(a, b);
    return vec2<f32>(low.x + low.y + low.z, high.x + high.y + high.z);
}

// 0..1 where `p` lies along `axis` across the box's range; the middle for a range of no extent.
fn box_along(lo: vec3<f32>, hi: vec3<f32>, axis: vec3<f32>, p: vec3<f32>) -> f32 {
    let range = box_range(lo, hi, axis);
    if range.y > range.x {
        return (dot(p, axis) - range.x) / (range.y - range.x);
    }
    return 0.5;
}

// The roof-view texel (continuous, in the page) where the view of axes `right`, `down` sees
// the roof point `p` of `cluster`.
fn roof_texel(cluster: TexturedCluster, right: vec3<f32>, down: vec3<f32>, p: vec3<f32>) -> vec2<f32> {
    let lo = cluster.box_lo_m.xyz;
    let hi = cluster.box_hi_m.xyz;
    let uv = vec2<f32>(box_along(lo, hi, right, p), box_along(lo, hi, down, p));
    return cluster.roof_rect_px.xy + clamp(uv, vec2<f32>(0.0), vec2<f32>(1.0)) * cluster.roof_rect_px.zw;
}
