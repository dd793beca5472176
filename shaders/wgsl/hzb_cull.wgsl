// Hierarchical-Z occlusion cull (engine `hzb::cull`), the GPU twin of `hzb::reference`'s
// `project_box` (frustum planes by corner outcodes, screen rectangle, nearest depth) and
// `DepthPyramid::is_occluded` (a 2x2 read at the coarse level as a shortcut, then at most
// HZB_FINE_SPAN x HZB_FINE_SPAN texels at the fine level), one invocation per box; a box that
// may be visible is tested again part by part, by the prisms its record names
// (reference `DepthPyramid::cull_record`).
//
// Each box is a `BuildingRecord` (bounds and index range). Its status is written as CULL_VISIBLE,
// CULL_FRUSTUM_OUTSIDE or CULL_OCCLUDED; every visible box appends its DrawIndexedIndirectArgs
// through an atomic counter.
//
// Visibility lives on the GPU (engine `frame`, niagara's drawVisibility): `stamps` holds, per
// draw id, the frame stamp of the last frame whose cull kept it; `parents` the draw id of the
// cluster above each draw id (NO_PARENT at a root). A building candidate was visible last frame
// when it, or a cluster above it, carries stamp `frame_stamp - 1` (a drawn cluster stands for
// every building under it); cluster candidates are never drawn early (their meshes are not
// contained in their buildings). Stale stamps expire by themselves.
//
// Three entry points, each over every candidate (box i stands for draw id draw_ids[i]):
// - `early`: candidates visible last frame and inside the frustum get CULL_VISIBLE, their draw
//   (the early pass draws those) and their drawn_early mark; the others CULL_NOT_EARLY.
// - `gate`: as `early`, but a candidate visible last frame is culled against the pyramid (the
//   occluders' own) and drawn and marked only when visible; its status is the cull's.
// - `cull`: every candidate against the pyramid; a visible one appends its draw unless
//   drawn_early marks it (drawn already), and is stamped with `frame_stamp`.

// Float rounding: the GPU's matrix product and division may round differently from the CPU's
// (FMA, reciprocal). Every comparison is widened in the visible direction by a bound on that
// difference (HZB_ROUNDING_REL times the magnitude of the terms), so the GPU never culls a box
// the CPU reference keeps: its rectangle contains the reference's, its nearest depth is not
// smaller, and a larger rectangle reads a superset of the reference's pixels at a level as
// coarse or coarser (pyramid texels are nested), so its farthest depth is not larger.
//
// llvmpipe trap 1 (shared/GPU-NOTES.md): a mip level that varies per invocation returned another
// level's data. The pyramid is read in a loop over levels with a uniform counter, and only when
// the counter equals one of this box's two levels. Levels are i32 (GL trap 3).

// Rust twin: citywalk_shaders::HzbCullParams.
struct HzbCullParams {
    // World to clip, reversed-Z (column-major).
    view_proj: mat4x4<f32>,
    // Viewport (= pyramid level 0) width and height in pixels.
    viewport_px: vec2<u32>,
    // Number of boxes (records) to test.
    box_count: u32,
    // Number of pyramid levels.
    level_count: u32,
    // Stamp of this frame's visible draw ids (last frame's is frame_stamp - 1).
    frame_stamp: u32,
    // Draw ids below this are buildings, the others cluster meshes.
    building_count: u32,
    // CULL_FLAG_DRAW_IDS | CULL_FLAG_VISIBILITY.
    flags: u32,
    _pad: u32,
}

// Per-frame parameters in a read-only storage buffer, not a uniform buffer: lavapipe (Mesa
// 22.3) inlines uniform values that steer control flow and recompiles the shader with LLVM
// whenever they change, 0.4-2.5 s a frame on a cold shader cache (engine `hzb::cull`).
@group(0) @binding(0) var<storage, read> params: HzbCullParams;
@group(0) @binding(1) var<storage, read> records: array<BuildingRecord>;
@group(0) @binding(2) var hzb: texture_2d<f32>;
@group(0) @binding(3) var<storage, read_write> status: array<u32>;
@group(0) @binding(4) var<storage, read_write> commands: array<DrawIndexedIndirectArgs>;
@group(0) @binding(5) var<storage, read_write> draw_count: atomic<u32>;
@group(0) @binding(6) var<storage, read> parts: array<CullPart>;
@group(0) @binding(7) var<storage, read_write> drawn_early: array<u32>;
@group(0) @binding(8) var<storage, read> draw_ids: array<u32>;
@group(0) @binding(9) var<storage, read_write> stamps: array<u32>;
@group(0) @binding(10) var<storage, read> parents: array<u32>;
// The frame's report (engine `frame::candidates`): the occluded and gate-culled counts, then
// the kept list and the early list of candidate indices, each with room for every candidate, so
// that the CPU reads what was drawn, never a word per candidate.
@group(0) @binding(23) var<storage, read_write> cull_report: array<atomic<u32>>;

// Where a box lands: status CULL_VISIBLE with `rect` valid only when `has_rect`.
struct Projection {
    status: u32,
    has_rect: bool,
    // x0, y0, x1, y1 (inclusive pixels, y down).
    rect: vec4<u32>,
    nearest_depth: f32,
}

// The eight corners of the box [lo, hi] (bit 0: x, 1: y, 2: z at hi).
fn box_corners(lo: vec3<f32>, hi: vec3<f32>) -> array<vec3<f32>, 8> {
    var corners: array<vec3<f32>, 8>;
    for (var i = 0u; i < 8u; i++) {
        corners[i] = vec3<f32>(
            select(lo.x, hi.x, (i & 1u) != 0u),
            select(lo.y, hi.y, (i & 2u) != 0u),
            select(lo.z, hi.z, (i & 4u) != 0u),
        );
    }
    return corners;
}

// The eight corners of a cull part (reference `CullPart::corners`): floor, then roof.
fn part_corners(part: CullPart) -> array<vec3<f32>, 8> {
    let xy = array<vec2<f32>, 4>(
        part.corners_xy[0].xy,
        part.corners_xy[0].zw,
        part.corners_xy[1].xy,
        part.corners_xy[1].zw,
    );
    var corners: array<vec3<f32>, 8>;
    for (var i = 0u; i < 4u; i++) {
        corners[i] = vec3<f32>(xy[i], part.z_min_m);
        corners[i + 4u] = vec3<f32>(xy[i], part.z_max_m);
    }
    return corners;
}

// Where the convex hull of `corners_in` lands (reference `project_corners`).
fn project(corners_in: array<vec3<f32>, 8>) -> Projection {
    var corners = corners_in;
    var out: Projection;
    out.status = CULL_VISIBLE;
    out.has_rect = false;
    let m = params.view_proj;
    let m_abs = mat4x4<f32>(abs(m[0]), abs(m[1]), abs(m[2]), abs(m[3]));
    var ndc_min = vec2<f32>(3.4e38);
    var ndc_max = vec2<f32>(-3.4e38);
    var nearest = 0.0;
    var all_behind = true;
    var crosses_near = false;
    // Frustum planes every corner surely lies beyond (reference `outcode`): right, left, top,
    // bottom, near; each test is widened by the rounding of both coordinates it compares.
    var beyond_all = 31u;
    for (var i = 0u; i < 8u; i++) {
        let corner = corners[i];
        let clip = m * vec4<f32>(corner, 1.0);
        let err = (m_abs * vec4<f32>(abs(corner), 1.0)) * HZB_ROUNDING_REL;
        let beyond = select(0u, 1u, clip.x > clip.w + (err.x + err.w))
            | select(0u, 2u, clip.x < -clip.w - (err.x + err.w))
            | select(0u, 4u, clip.y > clip.w + (err.y + err.w))
            | select(0u, 8u, clip.y < -clip.w - (err.y + err.w))
            | select(0u, 16u, clip.z > clip.w + (err.z + err.w));
        beyond_all &= beyond;
        // Surely behind the eye only if behind with any rounding.
        if clip.w > HZB_BEHIND_W - err.w {
            all_behind = false;
        }
        // Possibly behind the eye or between it and the near plane: no safe rectangle.
        if clip.w <= HZB_BEHIND_W + err.w || clip.z > clip.w - (err.z + err.w) {
            crosses_near = true;
            continue;
        }
        let ndc = clip.xyz / clip.w;
        let ndc_err = (err.xyz + abs(ndc) * err.w) / clip.w + abs(ndc) * HZB_ROUNDING_REL;
        ndc_min = min(ndc_min, ndc.xy - ndc_err.xy);
        ndc_max = max(ndc_max, ndc.xy + ndc_err.xy);
        nearest = max(nearest, ndc.z + ndc_err.z);
    }
    if all_behind || beyond_all != 0u {
        out.status = CULL_FRUSTUM_OUTSIDE;
        return out;
    }
    if crosses_near {
        return out;
    }
    if ndc_max.x < -1.0 || ndc_min.x > 1.0 || ndc_max.y < -1.0 || ndc_min.y > 1.0 {
        out.status = CULL_FRUSTUM_OUTSIDE;
        return out;
    }
    let size = vec2<f32>(params.viewport_px);
    // Pixel coordinates, widened by the rounding of this conversion.
    let px_err = size * HZB_ROUNDING_REL;
    let px_lo = clamp(
        vec2<f32>(ndc_min.x * 0.5 + 0.5, 0.5 - ndc_max.y * 0.5) * size - px_err,
        vec2<f32>(0.0),
        size - 1.0,
    );
    let px_hi = clamp(
        vec2<f32>(ndc_max.x * 0.5 + 0.5, 0.5 - ndc_min.y * 0.5) * size + px_err,
        vec2<f32>(0.0),
        size - 1.0,
    );
    out.has_rect = true;
    out.rect = vec4<u32>(vec2<u32>(floor(px_lo)), vec2<u32>(floor(px_hi)));
    out.nearest_depth = nearest;
    return out;
}

// The finest level at which the rectangle touches at most `span` texels each way (reference
// `level_spanning`): 2 for the coarse level (ceil, never floor), HZB_FINE_SPAN for the fine one.
fn level_spanning(rect: vec4<u32>, span: u32) -> u32 {
    var level = 0u;
    while (level < 31u && ((rect.z >> level) - (rect.x >> level) >= span || (rect.w >> level) - (rect.y >> level) >= span)) {
        level += 1u;
    }
    return level;
}

// Outcome of `test_hull` besides CULL_VISIBLE (a rectangle the pyramid does not hide),
// CULL_FRUSTUM_OUTSIDE and CULL_OCCLUDED: the hull reaches the near plane (no safe rectangle;
// visible).
const HULL_CROSSES_NEAR: u32 = 3u;

// The convex hull of `corners` against the frustum and the pyramid (reference
// `DepthPyramid::test_hull`); with `reads` false nothing is read (an invocation past the box
// count still runs the uniform level loop).
fn test_hull(corners: array<vec3<f32>, 8>, reads: bool) -> u32 {
    let p = project(corners);
    var coarse = -1;
    var fine = -1;
    if reads && p.has_rect {
        coarse = i32(min(level_spanning(p.rect, 2u), params.level_count - 1u));
        fine = i32(min(level_spanning(p.rect, HZB_FINE_SPAN), params.level_count - 1u));
    }
    // Uniform loop over levels, coarse to fine; each invocation reads only at the counter's
    // level (trap 1; in the loop over parts the active invocations still share the counter).
    // The coarse 2x2 read culls most hidden boxes; a box it keeps is decided by
    // the fine read, which skips the fine texels under coarse texels that hide the box and stops
    // at the first texel not in front of it (visible). Texels are nested (a texel is the
    // minimum of its descendants), so the answer is the fine level's alone: the reference's
    // `is_occluded`.
    var occluded = false;
    var decided = false;
    // Coarse texels (2x2, bit (y - y0) * 2 + (x - x0)) that do not hide the box: only the fine
    // texels under them are read (the others are hidden by their coarse ancestor already).
    var open_mask = 0u;
    var coarse_origin = vec2<u32>(0u);
    for (var level = i32(params.level_count) - 1; level >= 0; level--) {
        if level == coarse && !decided {
            let texels = covering_texels(p.rect, level);
            coarse_origin = texels.xy;
            for (var y = texels.y; y <= texels.w; y++) {
                for (var x = texels.x; x <= texels.z; x++) {
                    if textureLoad(hzb, vec2<i32>(i32(x), i32(y)), level).r <= p.nearest_depth {
                        open_mask |= 1u << ((y - texels.y) * 2u + (x - texels.x));
                    }
                }
            }
            // Hidden by the coarse texels, or the coarse level is the fine one: decided.
            occluded = open_mask == 0u;
            decided = occluded || coarse == fine;
        }
        if level == fine && !decided {
            let texels = covering_texels(p.rect, level);
            let shift = u32(coarse - level);
            occluded = true;
            for (var y = texels.y; y <= texels.w && occluded; y++) {
                let row = ((y >> shift) - coarse_origin.y) * 2u;
                for (var x = texels.x; x <= texels.z; x++) {
                    let bit = 1u << (row + (x >> shift) - coarse_origin.x);
                    if (open_mask & bit) != 0u
                        && textureLoad(hzb, vec2<i32>(i32(x), i32(y)), level).r <= p.nearest_depth {
                        occluded = false;
                        break;
                    }
                }
            }
            decided = true;
        }
    }
    if p.status != CULL_VISIBLE {
        return p.status;
    }
    if !p.has_rect {
        return HULL_CROSSES_NEAR;
    }
    return select(CULL_VISIBLE, CULL_OCCLUDED, occluded);
}

// One record: its box, then, when the box may be visible, its parts (reference
// `DepthPyramid::cull_record`): outside when every part is, hidden when none is visible. Every
// invocation calls it (the uniform level loop of `test_hull`); past the box count
// (`in_range` false) nothing is read and the answer is CULL_FRUSTUM_OUTSIDE.
fn record_outcome(record: BuildingRecord, in_range: bool) -> u32 {
    var outcome = test_hull(box_corners(record.bounds_min_m, record.bounds_max_m), in_range);
    if !in_range {
        return CULL_FRUSTUM_OUTSIDE;
    }
    let part_count = record.part_count;
    // Parts past the buffer (a malformed record) are not read: the box decides.
    let parts_valid = record.first_part < arrayLength(&parts)
        && part_count <= arrayLength(&parts) - record.first_part;
    let box_may_show = outcome == CULL_VISIBLE || outcome == HULL_CROSSES_NEAR;
    if box_may_show && part_count > 0u && parts_valid {
        var all_outside = true;
        var any_visible = false;
        for (var k = 0u; k < part_count && !any_visible; k++) {
            let s = test_hull(part_corners(parts[record.first_part + k]), true);
            any_visible = s == CULL_VISIBLE || s == HULL_CROSSES_NEAR;
            all_outside = all_outside && s == CULL_FRUSTUM_OUTSIDE;
        }
        let hidden = select(CULL_OCCLUDED, CULL_FRUSTUM_OUTSIDE, all_outside);
        outcome = select(hidden, CULL_VISIBLE, any_visible);
    }
    if outcome == HULL_CROSSES_NEAR {
        outcome = CULL_VISIBLE;
    }
    return outcome;
}

// Room in each of the report's two lists.
fn report_capacity() -> u32 {
    return (arrayLength(&cull_report) - CULL_R_WORDS) / 2u;
}

// Appends candidate `index` to the report list whose length is header word `length_word` and
// whose entries start at word `first` (a list that is full counts on, and the CPU sees it).
fn report_push(length_word: u32, first: u32, index: u32) {
    let slot = atomicAdd(&cull_report[length_word], 1u);
    if slot < report_capacity() {
        atomicStore(&cull_report[first + slot], index);
    }
}

// Appends the draw of `record`.
fn append_draw(record: BuildingRecord) {
    let slot = atomicAdd(&draw_count, 1u);
    commands[slot] = DrawIndexedIndirectArgs(record.index_count, 1u, record.first_index, record.base_vertex, 0u);
}

// The draw id box `index` stands for.
fn draw_id(index: u32) -> u32 {
    if (params.flags & CULL_FLAG_DRAW_IDS) != 0u && index < arrayLength(&draw_ids) {
        return draw_ids[index];
    }
    return index;
}

// The record of box `index` (clamped into the boxes and the records: every invocation reads one,
// in range or not, for the uniform level loop of `test_hull`).
fn record_of(index: u32) -> BuildingRecord {
    let id = draw_id(min(index, max(params.box_count, 1u) - 1u));
    return records[min(id, arrayLength(&records) - 1u)];
}

// Whether building draw id `id` was kept by last frame's cull, itself or through a cluster
// above it (the walk is bounded: a malformed parent chain ends after 64 steps).
fn visible_last_frame(id: u32) -> bool {
    if (params.flags & CULL_FLAG_VISIBILITY) == 0u || id >= params.building_count {
        return false;
    }
    let last = params.frame_stamp - 1u;
    var at = id;
    for (var step = 0u; step < 64u && at < arrayLength(&stamps); step++) {
        if stamps[at] == last {
            return true;
        }
        if at >= arrayLength(&parents) {
            return false;
        }
        at = parents[at];
    }
    return false;
}

// The early candidates: those visible last frame whose box lies in the frustum (the rest get
// CULL_NOT_EARLY); with `occlusion` (the gate) each is then culled against the pyramid, its
// parts included, and only a visible one is drawn and marked (the others keep the cull's status:
// kept out).
fn early_record(index: u32, occlusion: bool) {
    let in_range = index < params.box_count;
    let record = record_of(index);
    let eligible = in_range && visible_last_frame(draw_id(index));
    // The frustum alone: no reads.
    let in_frustum =
        test_hull(box_corners(record.bounds_min_m, record.bounds_max_m), false) != CULL_FRUSTUM_OUTSIDE;
    let takes = eligible && in_frustum;
    var outcome = CULL_VISIBLE;
    if occlusion {
        // Every invocation runs the uniform level loop; only those it takes read.
        outcome = record_outcome(record, takes);
    }
    if !in_range {
        return;
    }
    if !takes {
        status[index] = CULL_NOT_EARLY;
        return;
    }
    status[index] = outcome;
    if outcome == CULL_VISIBLE {
        append_draw(record);
        if index < arrayLength(&drawn_early) {
            drawn_early[index] = 1u;
        }
        report_push(CULL_R_EARLY, CULL_R_WORDS + report_capacity(), index);
    } else {
        atomicAdd(&cull_report[CULL_R_GATE_CULLED], 1u);
    }
}

// The early pass's candidates by the frustum alone (no occluders to gate them).
@compute @workgroup_size(HZB_CULL_WORKGROUP, 1, 1)
fn early(@builtin(global_invocation_id) id: vec3<u32>) {
    early_record(id.x, false);
}

// The occluder gate of the early pass: last frame's visible candidates against the occluders'
// pyramid.
@compute @workgroup_size(HZB_CULL_WORKGROUP, 1, 1)
fn gate(@builtin(global_invocation_id) id: vec3<u32>) {
    early_record(id.x, true);
}

// The cull of every candidate: status, the draw of each visible one not drawn early, and its
// visibility stamp.
@compute @workgroup_size(HZB_CULL_WORKGROUP, 1, 1)
fn cull(@builtin(global_invocation_id) id: vec3<u32>) {
    let index = id.x;
    let in_range = index < params.box_count;
    let record = record_of(index);
    let outcome = record_outcome(record, in_range);
    if !in_range {
        return;
    }
    status[index] = outcome;
    if outcome == CULL_OCCLUDED {
        atomicAdd(&cull_report[CULL_R_OCCLUDED], 1u);
    }
    let drawn = index < arrayLength(&drawn_early) && drawn_early[index] != 0u;
    if outcome == CULL_VISIBLE {
        report_push(CULL_R_KEPT, CULL_R_WORDS, index);
        if !drawn {
            append_draw(record);
        }
        if (params.flags & CULL_FLAG_VISIBILITY) != 0u {
            let d = draw_id(index);
            if d < arrayLength(&stamps) {
                stamps[d] = params.frame_stamp;
            }
        }
    }
}

// The texels of `level` covering `rect` (x0, y0, x1, y1, inclusive), inside the level's logical
// region (the texture is padded to powers of two).
fn covering_texels(rect: vec4<u32>, level: i32) -> vec4<u32> {
    let last = (params.viewport_px - 1u) >> vec2<u32>(u32(level));
    let lo = min(rect.xy >> vec2<u32>(u32(level)), last);
    let hi = min(rect.zw >> vec2<u32>(u32(level)), last);
    return vec4<u32>(lo, hi);
}

// ---- Tree cull: the LOD cut of the cluster tree on the GPU, with hierarchical occlusion ----
//
// Engine `hzb::tree_cull`; CPU reference `hzb::reference::tree_cull`. The cut of
// Chang et al. 2008 §8 / Yang et al. 2011 §4 (engine `lod`), walked top-down one tree level per
// dispatch (`tree_advance` sizes the next level's indirect dispatch from the queue), with each
// node's box (its cull record, which holds every building under it) tested against the frustum
// and the pyramid before its children are looked at: a hidden node hides its whole subtree, so
// the walk visits what is visible and its neighbours, not every node in the frustum. A node is in
// the cut when it is a leaf (its building, tested part by part) or its error projected at the
// nearest point of its bounds is within tolerance (its cluster mesh; with Chang's τ, each
// landmark rising more than τ above it too). The errors are monotone, so a node is in the cut
// exactly when its parent refines and it does not (the early entry's test).
//
// Kept draw ids go to this frame's half of the kept lists; the next frame's `tree_early` draws
// those of them that are buildings still in the cut and in the frustum (or, with the gate, not
// hidden by the occluders' pyramid) before the pyramid is built, and marks them in
// `early_marks` so that the walk appends no second draw. Clusters are never drawn early (their
// meshes are not contained in their buildings, so they must not feed the pyramid).

struct TreeCullParams {
    eye_m: vec3<f32>,
    px_per_m_at_1m: f32,
    criterion: u32,
    tolerance_a: f32,
    tolerance_b: f32,
    root: u32,
    list_capacity: u32,
    last_half: u32,
    early: u32,
    queue_capacity: u32,
    early_mark: u32,
    node_count: u32,
    building_count: u32,
    // Workgroups of each `tree_early` and `tree_level` dispatch (per adapter: engine
    // `hzb::tree_cull`).
    walk_workgroups: u32,
}

struct TreeNode {
    bounds_min_m: vec3<f32>,
    first_child: u32,
    bounds_max_m: vec3<f32>,
    child_count: u32,
    parent: u32,
    building: u32,
    building_count: u32,
    first_landmark: u32,
    landmark_count: u32,
    height_m: f32,
    chang_area_m2: f32,
    delta_h_m: f32,
    delta_a_m2: f32,
    has_error: u32,
    lod_error_m: f32,
    _pad: u32,
}

struct TreeLandmark {
    building: u32,
    top_m: f32,
}

// Two halves of kept draw ids (last frame's, this frame's), their counts in the header.
struct TreeLists {
    counts: array<atomic<u32>, TREE_LIST_HEADER>,
    ids: array<u32>,
}

// Storage, not uniform, as `params` (no per-frame recompilation on lavapipe).
@group(0) @binding(11) var<storage, read> tree: TreeCullParams;
@group(0) @binding(12) var<storage, read> nodes: array<TreeNode>;
@group(0) @binding(13) var<storage, read> children: array<u32>;
@group(0) @binding(14) var<storage, read> landmarks: array<TreeLandmark>;
@group(0) @binding(15) var<storage, read> leaf_of: array<u32>;
@group(0) @binding(16) var<storage, read_write> queue: array<u32>;
@group(0) @binding(17) var<storage, read_write> counters: array<atomic<u32>>;
@group(0) @binding(18) var<storage, read_write> lists: TreeLists;
@group(0) @binding(19) var<storage, read_write> early_ids: array<u32>;
@group(0) @binding(20) var<storage, read_write> early_commands: array<DrawIndexedIndirectArgs>;
@group(0) @binding(21) var<storage, read_write> late_commands: array<DrawIndexedIndirectArgs>;
@group(0) @binding(22) var<storage, read_write> early_marks: array<u32>;

// Pixels per metre at the nearest point of `node`'s bounds (engine `lod::LodView::px_per_m`);
// 0 when the eye is inside them (the caller treats that as infinitely close).
fn tree_px_per_m(node: TreeNode) -> f32 {
    let d = length(max(max(node.bounds_min_m - tree.eye_m, tree.eye_m - node.bounds_max_m), vec3<f32>(0.0)));
    if d <= 0.0 {
        return 0.0;
    }
    return tree.px_per_m_at_1m / d;
}

// Whether inner node `node` is refined (engine `lod::refine`).
fn tree_refines(node: TreeNode) -> bool {
    let ppm = tree_px_per_m(node);
    if ppm <= 0.0 {
        return node.has_error != 0u;
    }
    if tree.criterion == TREE_CRITERION_GEOMETRIC {
        return node.lod_error_m * ppm > tree.tolerance_a;
    }
    if tree.criterion == TREE_CRITERION_CHANG {
        return node.chang_area_m2 * ppm * ppm > tree.tolerance_a;
    }
    return node.delta_h_m > tree.tolerance_a / ppm || node.delta_a_m2 > tree.tolerance_b / (ppm * ppm);
}

fn tree_record(id: u32) -> BuildingRecord {
    return records[min(id, arrayLength(&records) - 1u)];
}

fn tree_overflow() {
    atomicOr(&counters[TREE_C_OVERFLOW], 1u);
}

// A visible draw id of the cut: its late draw unless the early entry drew it, and its entry in
// this frame's kept list.
fn tree_keep(id: u32, record: BuildingRecord) {
    let drawn_early = id < arrayLength(&early_marks) && early_marks[id] == tree.early_mark;
    if !drawn_early && record.index_count > 0u {
        let slot = atomicAdd(&counters[TREE_C_LATE_DRAWS], 1u);
        if slot < arrayLength(&late_commands) {
            late_commands[slot] = DrawIndexedIndirectArgs(record.index_count, 1u, record.first_index, record.base_vertex, 0u);
        } else {
            tree_overflow();
        }
    }
    let half = 1u - tree.last_half;
    let k = atomicAdd(&lists.counts[half], 1u);
    if k < tree.list_capacity {
        lists.ids[half * tree.list_capacity + k] = id;
    } else {
        tree_overflow();
    }
}

// Building `b` of the cut, tested part by part; `counted`: a culled one counts as culled (not for
// a landmark, whose cluster shows it already).
fn tree_keep_building(b: u32, counted: bool) {
    if b >= tree.building_count {
        return;
    }
    let record = tree_record(b);
    let outcome = record_outcome(record, true);
    if outcome == CULL_VISIBLE {
        tree_keep(b, record);
    } else if counted && outcome == CULL_FRUSTUM_OUTSIDE {
        atomicAdd(&counters[TREE_C_FRUSTUM_CULLED], 1u);
    } else if counted {
        atomicAdd(&counters[TREE_C_OCCLUSION_CULLED], 1u);
    }
}

// Resets the counters, takes last frame's kept count for the early entry and puts the root in
// level 0 of the queue.
@compute @workgroup_size(1, 1, 1)
fn tree_begin() {
    for (var i = 0u; i < TREE_C_WORDS; i++) {
        atomicStore(&counters[i], 0u);
    }
    atomicStore(&lists.counts[1u - tree.last_half], 0u);
    var last = 0u;
    if tree.early != TREE_EARLY_NONE {
        last = min(atomicLoad(&lists.counts[tree.last_half]), tree.list_capacity);
    }
    atomicStore(&counters[TREE_C_LAST_KEPT], last);
    var roots = 0u;
    if tree.root < tree.node_count && tree.queue_capacity > 0u {
        queue[0] = tree.root;
        roots = 1u;
    }
    atomicStore(&counters[TREE_C_QUEUE_LEN], roots);
}

// Last frame's kept buildings still in this frame's cut and in the frustum: drawn early and
// marked.
@compute @workgroup_size(HZB_CULL_WORKGROUP, 1, 1)
fn tree_early(@builtin(global_invocation_id) gid: vec3<u32>) {
    let count = atomicLoad(&counters[TREE_C_LAST_KEPT]);
    // Dispatched with `tree.walk_workgroups` workgroups (not read from `num_workgroups`, which
    // D3D12 reports as 0 without wgpu's indirect-call validation).
    let stride = tree.walk_workgroups * HZB_CULL_WORKGROUP;
    let rounds = (count + stride - 1u) / stride;
    for (var r = 0u; r < rounds; r++) {
        let i = gid.x + r * stride;
        var id = NO_PARENT;
        if i < count {
            id = lists.ids[tree.last_half * tree.list_capacity + i];
        }
        let takes = tree_early_takes(id);
        let record = tree_record(select(0u, id, takes));
        var outcome = CULL_VISIBLE;
        if test_hull(box_corners(record.bounds_min_m, record.bounds_max_m), false) == CULL_FRUSTUM_OUTSIDE {
            outcome = CULL_FRUSTUM_OUTSIDE;
        }
        if takes {
            tree_early_draw(id, record, outcome);
        }
    }
}

// Whether kept id `id` of last frame is a building still in this frame's cut as a leaf: its
// parent refines (and so, the errors being monotone, every ancestor does).
fn tree_early_takes(id: u32) -> bool {
    if id >= tree.building_count || id >= arrayLength(&leaf_of) {
        return false;
    }
    let leaf = leaf_of[id];
    if leaf >= arrayLength(&nodes) {
        return false;
    }
    let parent = nodes[leaf].parent;
    return parent == NO_PARENT || (parent < arrayLength(&nodes) && tree_refines(nodes[parent]));
}

// An early candidate's outcome: drawn early and marked when visible.
fn tree_early_draw(id: u32, record: BuildingRecord, outcome: u32) {
    if outcome != CULL_VISIBLE {
        return;
    }
    if id < arrayLength(&early_marks) {
        early_marks[id] = tree.early_mark;
    }
    let slot = atomicAdd(&counters[TREE_C_EARLY_DRAWS], 1u);
    if slot < arrayLength(&early_commands) {
        early_commands[slot] = DrawIndexedIndirectArgs(record.index_count, 1u, record.first_index, record.base_vertex, 0u);
    }
    let e = atomicAdd(&counters[TREE_C_EARLY_LISTED], 1u);
    if e < arrayLength(&early_ids) {
        early_ids[e] = id;
    }
}

// The current level's nodes, strided over the dispatch's invocations; the last workgroup to
// finish moves the walk to the next level (whose entries start after this level's).
// Invocations past the level's entries do nothing (a level is often far smaller than the
// dispatch).
@compute @workgroup_size(HZB_CULL_WORKGROUP, 1, 1)
fn tree_level(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) local: u32,
) {
    let l = min(atomicLoad(&counters[TREE_C_LEVEL]), TREE_MAX_LEVELS - 1u);
    let start = atomicLoad(&counters[TREE_C_QUEUE_START + l]);
    let len = atomicLoad(&counters[TREE_C_QUEUE_LEN + l]);
    for (var i = gid.x; i < len; i += tree.walk_workgroups * HZB_CULL_WORKGROUP) {
        if start + i < arrayLength(&queue) {
            tree_node(l, queue[start + i], start + len);
        }
    }
    storageBarrier();
    workgroupBarrier();
    if local == 0u {
        let done = atomicAdd(&counters[TREE_C_DONE], 1u) + 1u;
        if done == tree.walk_workgroups {
            atomicStore(&counters[TREE_C_DONE], 0u);
            let next = l + 1u;
            atomicStore(&counters[TREE_C_LEVEL], next);
            if next < TREE_MAX_LEVELS {
                atomicStore(&counters[TREE_C_QUEUE_START + next], start + len);
            }
        }
    }
}

// Node `n` of level `l`, whose children go to the next level from `next_start`: culled with
// its subtree, refined (its children queued), or in the cut (kept).
fn tree_node(l: u32, n: u32, next_start: u32) {
    if n >= arrayLength(&nodes) {
        return;
    }
    let node = nodes[n];
    let box_record = tree_record(tree.building_count + n);
    let outcome = test_hull(box_corners(box_record.bounds_min_m, box_record.bounds_max_m), true);
    atomicAdd(&counters[TREE_C_VISITED], 1u);
    if outcome == CULL_FRUSTUM_OUTSIDE {
        atomicAdd(&counters[TREE_C_FRUSTUM_CULLED], node.building_count);
        return;
    }
    if outcome == CULL_OCCLUDED {
        atomicAdd(&counters[TREE_C_OCCLUSION_CULLED], node.building_count);
        return;
    }
    if node.child_count == 0u {
        tree_keep_building(node.building, true);
        return;
    }
    if tree_refines(node) {
        if l + 1u >= TREE_MAX_LEVELS {
            tree_overflow();
            return;
        }
        let start = next_start + atomicAdd(&counters[TREE_C_QUEUE_LEN + l + 1u], node.child_count);
        for (var k = 0u; k < node.child_count; k++) {
            if start + k < arrayLength(&queue) && node.first_child + k < arrayLength(&children) {
                queue[start + k] = children[node.first_child + k];
            } else {
                tree_overflow();
            }
        }
        return;
    }
    // The cluster mesh: its box holds every building under it and was not hidden.
    tree_keep(tree.building_count + n, box_record);
    if tree.criterion == TREE_CRITERION_CHANG {
        // Chang et al. §8: τ projected to τ_height at the cluster (0 with the eye inside).
        let ppm = tree_px_per_m(node);
        var tau_height_m = 0.0;
        if ppm > 0.0 {
            tau_height_m = tree.tolerance_b / ppm;
        }
        for (var k = 0u; k < node.landmark_count; k++) {
            let at_k = node.first_landmark + k;
            if at_k < arrayLength(&landmarks) && landmarks[at_k].top_m - node.height_m > tau_height_m {
                tree_keep_building(landmarks[at_k].building, false);
            }
        }
    }
}
