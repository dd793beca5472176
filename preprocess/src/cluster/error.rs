//! citywalk's geometric and colour errors of the cluster meshes, the errors the default LOD
//! criterion projects (design: "Screen-space LOD"; the geometric error is the quantity 3D Tiles
//! 1.1 calls `geometricError`). The seeds have no such bound: Chang et al. 2008 §8's ε measures
//! negative space (zero for a terrace sharing walls) and τ catches only taller buildings.
//!
//! - **Vertical** departure of a cluster mesh (the hull extruded from its lowest base to its
//!   roof height `h`, [`roof_height_m`]): per building, `h − lowest top` (the roof above the
//!   building), `top − h` (the building rising through the roof) and `base − lowest base`
//!   (walls filling the space under a raised building); the largest over the node's buildings.
//! - **Plan** departure: the largest distance from a point of the hull to the union of the
//!   buildings' footprints (the one-sided Hausdorff distance, gaps and filled courtyards
//!   included), bounded from above within a few per cent by branch and bound: see
//!   [`plan_error_m`].
//! - The geometric error is `√(vertical² + plan²)`: every point of the cluster mesh is within it
//!   of a building's surface and every point of a building's surface within it of the mesh.
//!   The mesh's hull may then be cut inside the buildings by up to `√(error² − rise²)` in
//!   plan without breaking that (rise: the most a building's top rises above the mesh's
//!   roof; [`fill_errors`]' plan slack, [`super::simplify::cut_corners`]).
//! - **Colour**: the untextured mesh paints all its buildings one colour, so a pixel of a
//!   building's face may differ however small the geometric error is; it stays within the face's
//!   inradius of the face's edges. Bounded per building by half the second-smallest side of its
//!   bounding box (the largest inradius of the box's faces).
//!
//! Both are made monotone up the tree (the maximum with the children), so a cut that refines
//! while the projected error exceeds a tolerance is consistent.

use std::collections::BinaryHeap;

use citywalk_scenes::City;
use citywalk_scenes::city::Building;
use citywalk_scenes::cluster_tree::ClusterNode;
use geo::MultiPolygon;
use rayon::prelude::*;
use rstar::RTree;
use rstar::primitives::{GeomWithData, Rectangle};

use super::geom::{Pt, Side, closest_point_on_segment, locate, ring_bounds};

/// The geometric error (the plan error combined with the vertical one) is found to within this
/// share of itself, or within [`MIN_TOLERANCE_M`] or the hull's size over
/// [`SIZE_TOLERANCE_DIVISOR`], whichever is largest: a tenth of the error moves the distance at
/// which the cut refines the node by a tenth, and the error is found without refining the
/// whole boundary of a hull that hugs its buildings (where the true plan error is ~0).
const RELATIVE_TOLERANCE: f64 = 0.1;
/// Absolute tolerance (m): a pixel at 550 m in a 1280-pixel-wide, 60° view, about the
/// smallest slack of the sampling grid this replaces (0.48 m). Tighter, a hull that hugs its
/// buildings (true plan error 0) is refined all along its boundary.
const MIN_TOLERANCE_M: f64 = 0.5;
/// The absolute tolerance grows with the hull: 3.3 m on a 420 m cluster (the sampling grid
/// this replaces carried 50 m there).
const SIZE_TOLERANCE_DIVISOR: f64 = 128.0;
/// Distance queries per hull at most, so a node costs O(1) whatever its shape; past it the
/// largest bound still open is returned (an upper bound, only looser).
const MAX_QUERIES: usize = 1024;

/// When the search may stop: a plan distance `bound` adds nothing that matters to the
/// geometric error over the `lower` one already measured.
#[derive(Debug, Clone, Copy)]
pub struct Tolerance {
    vertical_m: f64,
    /// The node's error is at least this (its children's): a plan distance whose geometric
    /// error stays below it cannot change the node's.
    floor_m: f64,
    absolute_m: f64,
}

impl Tolerance {
    /// For a node of vertical error `vertical_m` whose children's geometric error is
    /// `floor_m`; [`plan_error_m`] sets the absolute part from the hull's size.
    pub fn new(vertical_m: f64, floor_m: f64) -> Tolerance {
        Tolerance {
            vertical_m,
            floor_m,
            absolute_m: MIN_TOLERANCE_M,
        }
    }

    fn for_hull(self, hull_size_m: f64) -> Tolerance {
        Tolerance {
            absolute_m: MIN_TOLERANCE_M.max(hull_size_m / SIZE_TOLERANCE_DIVISOR),
            ..self
        }
    }

    fn covers(&self, bound: f64, lower: f64) -> bool {
        let reached = (self.vertical_m * self.vertical_m + lower * lower).sqrt();
        let geometric = (self.vertical_m * self.vertical_m + bound * bound).sqrt();
        geometric <= self.floor_m
            || geometric <= reached + self.absolute_m.max(RELATIVE_TOLERANCE * reached)
    }
}

/// The buildings' footprints indexed for distance queries: an R-tree of their bounding boxes,
/// each carrying the building's position in the tree's `building_order`, so "a building of
/// this node" is a range test. The edges stay in the city: an R-tree of every edge of a
/// million-building city held 0.6 GB while the tiles' top was measured, the run's peak.
#[derive(Debug)]
pub struct Footprints<'a> {
    city: &'a City,
    order: &'a [citywalk_scenes::BuildingId],
    boxes: RTree<GeomWithData<Rectangle<Pt>, u32>>,
    /// Footprint edges (every ring) of the buildings before each position in the tree order:
    /// `order[a .. b]` has `first_edge[b] - first_edge[a]` edges.
    first_edge: Vec<u32>,
}

/// Below this many edges a node's distance is measured over its own edges directly
/// ([`NodeFootprints`]).
const DIRECT_EDGES: u32 = 192;

impl<'a> Footprints<'a> {
    pub fn new(city: &'a City, order: &'a [citywalk_scenes::BuildingId]) -> Footprints<'a> {
        let mut edge_count = 0u32;
        let mut boxes = Vec::with_capacity(order.len());
        let mut first_edge = Vec::with_capacity(order.len() + 1);
        for (pos, b) in order.iter().enumerate() {
            let footprint = &city.buildings[b.index()].footprint;
            first_edge.push(edge_count);
            edge_count += edges_of(footprint).count() as u32;
            if let Some(r) = geo::BoundingRect::bounding_rect(footprint) {
                let rect = Rectangle::from_corners([r.min().x, r.min().y], [r.max().x, r.max().y]);
                boxes.push(GeomWithData::new(rect, pos as u32));
            }
        }
        first_edge.push(edge_count);
        Footprints {
            city,
            order,
            boxes: RTree::bulk_load(boxes),
            first_edge,
        }
    }

    /// Distance (m) from `p` to the footprints of the buildings at `order[range.0 .. range.1]`;
    /// 0 inside or on one.
    pub fn distance_m(&self, p: Pt, range: (u32, u32)) -> f64 {
        self.of_node(range).distance_m(p)
    }

    /// The footprints of the buildings `range` (a node's), ready for many distance queries.
    fn of_node(&self, range: (u32, u32)) -> NodeFootprints<'_> {
        let (first, end) = (
            self.first_edge[range.0 as usize],
            self.first_edge[range.1 as usize],
        );
        if end - first <= DIRECT_EDGES {
            self.direct(range)
        } else {
            NodeFootprints::Indexed { fp: self, range }
        }
    }

    /// The node's own edges, copied once from the city for the node's queries (a few kB).
    fn direct(&self, range: (u32, u32)) -> NodeFootprints<'_> {
        let mut edges = Vec::new();
        let mut ends = Vec::with_capacity((range.1 - range.0) as usize);
        for pos in range.0..range.1 {
            edges.extend(edges_of(self.footprint_at(pos)));
            ends.push(edges.len());
        }
        NodeFootprints::Direct { edges, ends }
    }

    /// The footprint of the building at `pos` in the tree order.
    fn footprint_at(&self, pos: u32) -> &MultiPolygon<f64> {
        &self.city.buildings[self.order[pos as usize].index()].footprint
    }

    /// [`Footprints::distance_m`] through the R-tree of all the footprints' boxes: the node's
    /// buildings in order of their box's distance from `p` (a lower bound of theirs), each
    /// measured until the next box is no nearer than the nearest footprint found.
    fn distance_indexed_m(&self, p: Pt, range: (u32, u32)) -> f64 {
        let mine = |pos: u32| (range.0..range.1).contains(&pos);
        let mut nearest2 = f64::INFINITY;
        for (b, box2) in self.boxes.nearest_neighbor_iter_with_distance_2(p) {
            if box2 >= nearest2 {
                break;
            }
            if mine(b.data) {
                nearest2 = nearest2.min(distance2_to_rings(edges_of(self.footprint_at(b.data)), p));
                if nearest2 == 0.0 {
                    break;
                }
            }
        }
        nearest2.sqrt()
    }
}

/// The edges of every ring of a footprint.
fn edges_of(footprint: &MultiPolygon<f64>) -> impl Iterator<Item = [Pt; 2]> + '_ {
    footprint.0.iter().flat_map(|poly| {
        std::iter::once(poly.exterior())
            .chain(poly.interiors())
            .flat_map(|ring| ring.lines())
            .map(|l| [[l.start.x, l.start.y], [l.end.x, l.end.y]])
    })
}

/// The squared distance from `p` to one building's footprint given as the edges of all its
/// rings: 0 inside it (crossing parity over the rings, holes included), else to the nearest
/// edge.
fn distance2_to_rings(edges: impl Iterator<Item = [Pt; 2]>, p: Pt) -> f64 {
    let mut nearest2 = f64::INFINITY;
    let mut inside = false;
    for [a, b] in edges {
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < a[0] + (p[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0])
        {
            inside = !inside;
        }
        let q = closest_point_on_segment(p, a, b);
        nearest2 = nearest2.min((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2));
    }
    if inside { 0.0 } else { nearest2 }
}

/// One node's footprints for its distance queries. Small nodes (most of a tree) measure over
/// their own edges directly, several times cheaper than walking the R-tree's nearest
/// neighbours, which also meets the other nodes' edges.
enum NodeFootprints<'a> {
    /// The node's edges, building after building: building k's end at `ends[k]`.
    Direct {
        edges: Vec<[Pt; 2]>,
        ends: Vec<usize>,
    },
    Indexed {
        fp: &'a Footprints<'a>,
        range: (u32, u32),
    },
}

impl NodeFootprints<'_> {
    /// Distance (m) from `p` to the node's footprints: 0 inside one (crossing parity over each
    /// building's rings, holes included), else the nearest edge.
    fn distance_m(&self, p: Pt) -> f64 {
        let (edges, ends) = match self {
            NodeFootprints::Indexed { fp, range } => return fp.distance_indexed_m(p, *range),
            NodeFootprints::Direct { edges, ends } => (edges, ends),
        };
        let mut nearest2 = f64::INFINITY;
        let mut start = 0;
        for &end in ends {
            let d2 = distance2_to_rings(edges[start..end].iter().copied(), p);
            if d2 == 0.0 {
                return 0.0;
            }
            nearest2 = nearest2.min(d2);
            start = end;
        }
        nearest2.sqrt()
    }
}

/// An upper bound (m) of the largest distance from a point of the hull `ring` to the
/// footprints of the buildings `range` (the plan part of the geometric error), close enough
/// to the true value that the geometric error it makes with the tolerance's vertical error is
/// within [`RELATIVE_TOLERANCE`] (or the absolute tolerance) of the true one, or below the
/// tolerance's floor when the true one is (then the node's error is the floor anyway).
///
/// Branch and bound over square cells, the way the pole of inaccessibility is found
/// (Garcia-Castellanos & Lombardo 2007, "Poles of inaccessibility"): the distance is
/// 1-Lipschitz, so a cell of half-diagonal `r` whose centre lies at distance `d` holds no point
/// farther than `d + r`. The cell with the largest such bound is split into four until that
/// bound is within the tolerance of the largest distance measured at a point of the hull.
/// Cells wholly outside the hull are dropped; a cell straddling its boundary is measured at
/// the boundary point nearest its centre (a point of the hull). The sampling grid this
/// replaces carried a slack of (√2 + ½) × its spacing, 50 m on a 420 m cluster, which held
/// far views at a finer cut than their buildings need.
pub fn plan_error_m(
    fp: &Footprints<'_>,
    verts: &[Pt],
    ring: &[u32],
    range: (u32, u32),
    tolerance: Tolerance,
) -> f64 {
    if ring.len() < 3 {
        return 0.0;
    }
    let (lo, hi) = ring_bounds(verts, ring);
    let half = 0.5 * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    let tolerance = tolerance.for_hull(2.0 * half);
    let footprints = fp.of_node(range);
    let mut lower = 0.0f64;
    // The largest bound of a cell given up because it could not beat `lower` by the
    // tolerance: the result must still cover it.
    let mut given_up = 0.0f64;
    let mut open: BinaryHeap<Cell> = BinaryHeap::new();
    let visit = |centre: Pt, half: f64, lower: &mut f64, given_up: &mut f64| {
        let radius = half * std::f64::consts::SQRT_2;
        let bound = if locate(verts, ring, centre) == Side::Outside {
            let (edge_distance, nearest) = nearest_on_ring(verts, ring, centre);
            if edge_distance > radius {
                return None;
            }
            let d = footprints.distance_m(nearest);
            *lower = lower.max(d);
            d + edge_distance + radius
        } else {
            let d = footprints.distance_m(centre);
            *lower = lower.max(d);
            d + radius
        };
        if tolerance.covers(bound, *lower) {
            *given_up = given_up.max(bound);
            return None;
        }
        Some(Cell {
            bound,
            centre,
            half,
        })
    };
    let centre = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
    open.extend(visit(centre, half, &mut lower, &mut given_up));
    let mut queries = 1;
    while let Some(cell) = open.peek() {
        if tolerance.covers(cell.bound, lower) || queries >= MAX_QUERIES {
            break;
        }
        let Cell { centre, half, .. } = open.pop().expect("peeked");
        let h = 0.5 * half;
        queries += 4;
        for (dx, dy) in [(-h, -h), (h, -h), (-h, h), (h, h)] {
            open.extend(visit(
                [centre[0] + dx, centre[1] + dy],
                h,
                &mut lower,
                &mut given_up,
            ));
        }
    }
    let still_open = open.peek().map_or(0.0, |c| c.bound);
    lower.max(given_up).max(still_open)
}

/// A square cell of the plan-error search and the largest distance any point of it can have.
#[derive(Debug, Clone, Copy)]
struct Cell {
    bound: f64,
    centre: Pt,
    half: f64,
}

impl PartialEq for Cell {
    fn eq(&self, other: &Cell) -> bool {
        self.bound.total_cmp(&other.bound).is_eq()
    }
}
impl Eq for Cell {}
impl PartialOrd for Cell {
    fn partial_cmp(&self, other: &Cell) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Cell {
    fn cmp(&self, other: &Cell) -> std::cmp::Ordering {
        self.bound.total_cmp(&other.bound)
    }
}

/// The distance from `p` to the ring's boundary and the boundary point nearest `p`.
fn nearest_on_ring(verts: &[Pt], ring: &[u32], p: Pt) -> (f64, Pt) {
    let mut best = (f64::INFINITY, p);
    for i in 0..ring.len() {
        let (a, b) = (
            verts[ring[i] as usize],
            verts[ring[(i + 1) % ring.len()] as usize],
        );
        let q = closest_point_on_segment(p, a, b);
        let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
        if d2 < best.0 {
            best = (d2, q);
        }
    }
    (best.0.sqrt(), best.1)
}

/// A building's heights as the vertical error and the roof height read them.
#[derive(Debug, Clone, Copy)]
pub struct Heights {
    base_m: f32,
    top_m: f32,
    /// The lowest point of its roof: the lowest part top, and for a mesh the lowest corner of
    /// an upward-facing triangle (the eaves of a pitched roof); never below its base.
    pub lowest_top_m: f32,
    /// Half the second-smallest side of its bounding box (the colour error).
    colour_m: f32,
}

/// Every building's [`Heights`], in `building_order` (the order of the nodes' building ranges).
pub fn building_heights(
    city: &City,
    building_order: &[citywalk_scenes::BuildingId],
) -> Vec<Heights> {
    building_order
        .iter()
        .map(|b| heights(&city.buildings[b.index()]))
        .collect()
}

fn heights(b: &Building) -> Heights {
    let (lo, hi) = b.bounds();
    let mut sides = [hi.x - lo.x, hi.y - lo.y, b.top_m - b.base_m].map(|v| v.max(0.0));
    sides.sort_by(f32::total_cmp);
    Heights {
        base_m: b.base_m,
        top_m: b.top_m,
        lowest_top_m: lowest_top_m(b),
        colour_m: 0.5 * sides[1],
    }
}

fn lowest_top_m(b: &Building) -> f32 {
    let mut lowest = b.parts.iter().map(|p| p.top_m).fold(b.top_m, f32::min);
    if let Some(mesh) = &b.mesh {
        for [p, q, r] in mesh.triangles() {
            let n = (q - p).cross(r - p);
            // Facing up (within 60° of vertical): a roof, not a wall.
            if n.z > 0.5 * n.length() {
                lowest = lowest.min(p.z.min(q.z).min(r.z));
            }
        }
    }
    lowest.max(b.base_m)
}

/// The height of a cluster mesh's roof (m): the one that minimises its vertical error's roof
/// terms, `max(h − lowest roof point, highest top − h)`, over its buildings — midway between
/// the lowest roof point and the highest top — kept within the buildings' tops
/// `[lowest top, highest top]`. citywalk's choice: Chang et al. 2008 eq. 5 puts the roof at
/// the area-weighted mean height, which stands far above the low parts of a city of podiums
/// and towers; those nodes then carry the largest errors and hold the far views' cut down
/// (generated 100k at 1.02 diameters: 5.18 → 4.14 % of the full triangles, BENCHMARKS.md
/// "Far views: the cluster roof").
pub fn roof_height_m(lowest_roof_m: f32, h_min_m: f32, h_max_m: f32) -> f32 {
    (0.5 * (lowest_roof_m + h_max_m)).clamp(h_min_m.min(h_max_m), h_max_m)
}

/// Fills `geometric_error_m` and `colour_error_m` of every node (heights and footprints
/// already set; nodes in depth-first preorder, children after their parent). Returns each
/// node's plan slack (m): the horizontal departure its geometric error allows a building point
/// left outside the mesh's walls, beside the most a building rises through its roof,
/// `√(error² − rise²)`; its cluster mesh may leave a building's point this far outside
/// without raising the error ([`super::simplify::cut_corners`]).
pub fn fill_errors(
    city: &City,
    verts: &[Pt],
    building_order: &[citywalk_scenes::BuildingId],
    per_building: &[Heights],
    nodes: &mut [ClusterNode],
) -> Vec<f32> {
    let mut plan_slack_m = vec![0.0f32; nodes.len()];
    let fp = Footprints::new(city, building_order);
    // Bottom-up, one depth at a time, the nodes of a depth on rayon's threads: a node's error
    // is the maximum of its own and its children's, so its children's (already final) are a
    // floor below which its own search need not look.
    let deepest = nodes.iter().map(|n| n.depth as usize).max().unwrap_or(0);
    let mut by_depth: Vec<Vec<usize>> = vec![Vec::new(); deepest + 1];
    for (id, node) in nodes.iter().enumerate() {
        by_depth[node.depth as usize].push(id);
    }
    for ids in by_depth.iter().rev() {
        let errors: Vec<(f32, f32, f32)> = ids
            .par_iter()
            .map(|&id| node_errors(&fp, verts, per_building, nodes, id))
            .collect();
        for (&id, (geometric, colour, slack)) in ids.iter().zip(errors) {
            nodes[id].geometric_error_m = geometric;
            nodes[id].colour_error_m = colour;
            plan_slack_m[id] = slack;
        }
    }
    plan_slack_m
}

/// Node `id`'s geometric error, colour error and plan slack ([`fill_errors`]), its children's
/// errors already final: a node's error is the maximum of its own and its children's, so its
/// children's are a floor below which its own search need not look.
pub fn node_errors(
    fp: &Footprints<'_>,
    verts: &[Pt],
    per_building: &[Heights],
    nodes: &[ClusterNode],
    id: usize,
) -> (f32, f32, f32) {
    let node = &nodes[id];
    let (floor_geometric, floor_colour) =
        node.children
            .iter()
            .fold((0.0f32, 0.0f32), |(g, c), &child| {
                let child = &nodes[child as usize];
                (g.max(child.geometric_error_m), c.max(child.colour_error_m))
            });
    let own = own_errors(fp, verts, per_building, node, floor_geometric);
    let geometric = own.geometric_m.max(floor_geometric);
    let slack = (geometric * geometric - own.rise_m * own.rise_m)
        .max(0.0)
        .sqrt();
    (geometric, own.colour_m.max(floor_colour), slack)
}

/// A node's own errors (m), before the maximum with its children's.
struct OwnErrors {
    geometric_m: f32,
    /// The most a building rises through the mesh's roof: the only vertical distance from a
    /// building point that a cut corner leaves outside the walls to the mesh (the walls span
    /// the lowest base to the roof).
    rise_m: f32,
    colour_m: f32,
}

/// A node's own geometric and colour error and its rise (m), not yet the maximum with its
/// children's; the geometric one found only as far as it can exceed `floor_m`.
fn own_errors(
    fp: &Footprints<'_>,
    verts: &[Pt],
    per_building: &[Heights],
    node: &ClusterNode,
    floor_m: f32,
) -> OwnErrors {
    if node.is_leaf() {
        return OwnErrors {
            geometric_m: 0.0,
            rise_m: 0.0,
            colour_m: 0.0,
        };
    }
    let HeightTerms {
        vertical_m: vertical,
        rise_m: rise,
        colour_m: colour,
    } = height_terms(per_building, node);
    let plan = node.footprint.first().map_or(0.0, |ring| {
        let tolerance = Tolerance::new(f64::from(vertical), f64::from(floor_m));
        plan_error_m(fp, verts, ring, node.buildings, tolerance)
    });
    OwnErrors {
        geometric_m: f64::from(vertical).hypot(plan) as f32,
        rise_m: rise,
        colour_m: colour,
    }
}

/// The terms of a node's errors that its buildings' heights alone decide.
struct HeightTerms {
    /// The mesh's largest vertical departure from a building (roof above or below a top,
    /// walls below a base).
    vertical_m: f32,
    /// The most a building rises through the mesh's roof.
    rise_m: f32,
    /// The largest colour error of its buildings.
    colour_m: f32,
}

fn height_terms(per_building: &[Heights], node: &ClusterNode) -> HeightTerms {
    let (s, e) = node.buildings;
    let mine = &per_building[s as usize..e as usize];
    let base = mine.iter().map(|h| h.base_m).fold(f32::INFINITY, f32::min);
    // The mesh's base, as `build_meshes` extrudes it.
    let base = base.min(node.height_m);
    let vertical = mine
        .iter()
        .map(|h| {
            (node.height_m - h.lowest_top_m)
                .max(h.top_m - node.height_m)
                .max(h.base_m - base)
        })
        .fold(0.0f32, f32::max);
    HeightTerms {
        vertical_m: vertical,
        rise_m: mine
            .iter()
            .map(|h| h.top_m - node.height_m)
            .fold(0.0f32, f32::max),
        colour_m: mine.iter().map(|h| h.colour_m).fold(0.0f32, f32::max),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use citywalk_scenes::{BuildingId, Frame, HeightSource, LoadReport};
    use geo::{LineString, MultiPolygon, Polygon};

    fn rect_building(id: u32, x0: f64, y0: f64, x1: f64, y1: f64, top: f32) -> Building {
        let ring = LineString::from(vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]);
        Building {
            id: BuildingId(id),
            source_id: format!("b{id}"),
            footprint: MultiPolygon(vec![Polygon::new(ring, vec![])]),
            parts: vec![],
            base_m: 0.0,
            top_m: top,
            height_source: HeightSource::Tagged,
            mesh: None,
            tags: Default::default(),
        }
    }

    fn city_of(buildings: Vec<Building>) -> City {
        City {
            frame: Frame::local(),
            buildings,
            streets: vec![],
            ground_areas: Vec::new(),
            report: LoadReport::default(),
        }
    }

    #[test]
    fn plan_error_bounds_the_gap_between_two_buildings() {
        // Two 10 × 10 m buildings 6 m apart; the hull is their bounding box (26 × 10 m): the
        // point farthest from both is the gap's centre line, 3 m from each.
        let city = city_of(vec![
            rect_building(0, 0.0, 0.0, 10.0, 10.0, 10.0),
            rect_building(1, 16.0, 0.0, 26.0, 10.0, 10.0),
        ]);
        let order = vec![BuildingId(0), BuildingId(1)];
        let fp = Footprints::new(&city, &order);
        let verts = vec![[0.0, 0.0], [26.0, 0.0], [26.0, 10.0], [0.0, 10.0]];
        // The bound is within the tolerance of the true value.
        let e = plan_error_m(&fp, &verts, &[0, 1, 2, 3], (0, 2), Tolerance::new(0.0, 0.0));
        assert!(e >= 3.0, "{e} below the true 3 m");
        assert!(
            e <= 3.0 + MIN_TOLERANCE_M + 1e-9,
            "{e} far above the true 3 m"
        );
        // Only building 0 belongs to the node: the far end of the hull is 16 m from it.
        let e0 = plan_error_m(&fp, &verts, &[0, 1, 2, 3], (0, 1), Tolerance::new(0.0, 0.0));
        assert!(e0 >= 16.0, "{e0}");
        assert!(e0 <= 16.0 * (1.0 + RELATIVE_TOLERANCE) + 1e-9, "{e0}");
        // A hull equal to the footprints has only the tolerance.
        let tight = vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        assert!(
            plan_error_m(&fp, &tight, &[0, 1, 2, 3], (0, 1), Tolerance::new(0.0, 0.0))
                <= MIN_TOLERANCE_M + 1e-9
        );
        // Beside a vertical error of 4 m, the plan error of the gap (3 m) is found only as
        // closely as the geometric error √(4² + 3²) = 5 m needs.
        let v = plan_error_m(&fp, &verts, &[0, 1, 2, 3], (0, 2), Tolerance::new(4.0, 0.0));
        assert!(
            v >= 3.0 && 4f64.hypot(v) <= 5.0 * (1.0 + RELATIVE_TOLERANCE) + 1e-9,
            "{v}"
        );
        // Children's error of 20 m, above the node's own 16 m: the search may stop anywhere
        // below 20 m; with a floor of 10 m it still finds the 16 m.
        let of_building_0 = |floor_m: f64| {
            plan_error_m(
                &fp,
                &verts,
                &[0, 1, 2, 3],
                (0, 1),
                Tolerance::new(0.0, floor_m),
            )
        };
        let under = of_building_0(20.0);
        assert!(under <= 20.0, "{under}");
        let found = of_building_0(10.0);
        assert!(found >= 16.0, "{found}");
    }

    proptest::proptest! {
        /// The bound covers every point of the hull (here a dense grid: each point of the hull
        /// lies within half a grid cell's diagonal of a grid point) and is within the tolerance
        /// of the largest distance.
        #[test]
        fn plan_error_is_a_tight_upper_bound(
            rects in proptest::collection::vec((0.0f64..50.0, 0.0f64..30.0, 1.0f64..15.0, 1.0f64..15.0), 1..5)
        ) {
            let buildings: Vec<Building> = rects
                .iter()
                .enumerate()
                .map(|(i, &(x, y, w, h))| rect_building(i as u32, x, y, x + w, y + h, 10.0))
                .collect();
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for &(x, y, w, h) in &rects {
                lo = [lo[0].min(x), lo[1].min(y)];
                hi = [hi[0].max(x + w), hi[1].max(y + h)];
            }
            let order: Vec<BuildingId> = (0..buildings.len() as u32).map(BuildingId).collect();
            let city = city_of(buildings);
            let fp = Footprints::new(&city, &order);
            let verts = vec![lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]];
            let range = (0, order.len() as u32);
            let e = plan_error_m(&fp, &verts, &[0, 1, 2, 3], range, Tolerance::new(0.0, 0.0));
            let step = 0.5;
            let mut sampled = 0.0f64;
            let (nx, ny) = (((hi[0] - lo[0]) / step).ceil() as usize, ((hi[1] - lo[1]) / step).ceil() as usize);
            for j in 0..=ny {
                for i in 0..=nx {
                    let p = [(lo[0] + i as f64 * step).min(hi[0]), (lo[1] + j as f64 * step).min(hi[1])];
                    sampled = sampled.max(fp.distance_m(p, range));
                }
            }
            let most = sampled + step * std::f64::consts::FRAC_1_SQRT_2;
            let size = (hi[0] - lo[0]).max(hi[1] - lo[1]);
            proptest::prop_assert!(e >= sampled - 1e-9, "{e} below a sampled {sampled}");
            // The direct measure of small nodes agrees with the R-tree's.
            for p in [lo, hi, [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])], [lo[0] + 3.0, hi[1] - 2.0]] {
                let (direct, indexed) = (fp.direct(range).distance_m(p), fp.distance_indexed_m(p, range));
                proptest::prop_assert!((direct - indexed).abs() < 1e-9, "{direct} against {indexed} at {p:?}");
            }
            proptest::prop_assert!(
                Tolerance::new(0.0, 0.0).for_hull(size).covers(e, most),
                "{e} above the tolerance over {sampled}"
            );
        }
    }

    proptest::proptest! {
        /// The roof height gives the least vertical error of any roof within the buildings'
        /// tops: `max(h − lowest roof point, highest top − h)` is no larger at it than at any
        /// other such height (the area-weighted mean among them).
        #[test]
        fn roof_height_has_the_least_vertical_error(
            lowest in 0.0f32..100.0, up in 0.0f32..100.0, range in 0.0f32..200.0, t in 0.0f32..=1.0
        ) {
            let (h_min, h_max) = (lowest + up, lowest + up + range);
            let roof_error = |h: f32| (h - lowest).max(h_max - h);
            let h = roof_height_m(lowest, h_min, h_max);
            proptest::prop_assert!((h_min..=h_max).contains(&h));
            let other = h_min + t * (h_max - h_min);
            proptest::prop_assert!(roof_error(h) <= roof_error(other) + 1e-3);
        }
    }

    #[test]
    fn roof_stands_midway_within_the_tops() {
        assert_eq!(roof_height_m(9.0, 9.0, 120.0), 64.5);
        // A low part far below every top: the roof stays at the lowest top.
        assert_eq!(roof_height_m(2.0, 10.0, 12.0), 10.0);
    }

    #[test]
    fn colour_error_is_half_the_middle_side() {
        let b = rect_building(0, 0.0, 0.0, 8.0, 30.0, 12.0);
        assert_eq!(heights(&b).colour_m, 6.0);
    }
}
