// Cluster texture bake (Chang et al. 2008 §7): the buildings of one cluster, each scaled
// vertically so that its top meets the cluster's roof, in one orthographic view; writes their
// albedo (the target is sRGB), so the runtime lights the textured cluster mesh itself.
// Faces turned up (a normal within 45° of vertical) take the roof colour, the rest the
// facade colour, as the scene pass colours them.

// The views of one batch of draws; each draw's instance index picks its own.
@group(0) @binding(0) var<storage, read> views: array<BakeView>;
// Per building id, its top (m): the scale of its heights is roof / top.
@group(0) @binding(1) var<storage, read> building_tops_m: array<f32>;

struct VertexOutput {
    @builtin(position) clip: vec4<f32>,
    @location(0) world_m: vec3<f32>,
    @location(1) @interpolate(flat) building_id: u32,
}

@vertex
fn vs_main(v: SceneVertex, @builtin(instance_index) view_index: u32) -> VertexOutput {
    let bake = views[view_index];
    let top = building_tops_m[v.building_id];
    let scale = select(1.0, bake.params.x / top, top > 0.0);
    let p = vec3<f32>(v.position_m.xy, v.position_m.z * scale);
    var out: VertexOutput;
    out.clip = bake.world_to_clip * vec4<f32>(p, 1.0);
    out.world_m = p;
    out.building_id = v.building_id;
    return out;
}

@fragment
fn fs_main(in: VertexOutput) -> @location(0) vec4<f32> {
    let n = normalize(cross(dpdy(in.world_m), dpdx(in.world_m)));
    var albedo = facade_colour(in.building_id);
    if abs(n.z) > 0.7 {
        albedo = roof_colour(in.building_id);
    }
    return vec4<f32>(albedo, 1.0);
}
