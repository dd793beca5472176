//! Urban blocks: the faces of the street network, and the assignment of buildings to them.
//!
//! This work is based on Pina, Serón, Cerezo, *Accelerating urban scenes visualization using a
//! quadtree decomposition of urban blocks* (§3): "block status is assigned to any portion of
//! terrain completely surrounded by streets", and every element of the city is assigned to
//! exactly one block. The paper starts from streets already identified in a GIS; here the
//! blocks are computed by polygonising the street centre lines whose class bounds blocks
//! ([`StreetClass::bounds_blocks`](citywalk_scenes::StreetClass::bounds_blocks)):
//!
//! 1. **Noding**: every pair of segments whose boxes overlap (found with an `rstar` tree) is
//!    classified with the exact `robust::orient2d` predicate; crossings, touches and collinear
//!    overlaps add split points to both segments.
//! 2. **Snapping**: split points are rounded to a grid of [`BlockParams::snap_tolerance_m`]
//!    (1 cm by default) so nearly equal points become one graph vertex.
//! 3. **Planar graph**: undirected edges between consecutive split points, duplicates merged;
//!    dangling edges (chains ending in a vertex of degree 1) are pruned repeatedly.
//! 4. **Faces**: the classic planar-face traversal of a doubly connected edge list (de Berg,
//!    van Kreveld, Overmars, Schwarzkopf, *Computational Geometry*, 3rd ed., §2.2): the
//!    half-edges leaving each vertex are sorted by angle, and the successor of the half-edge
//!    `u → v` is the half-edge leaving `v` that comes next clockwise after `v → u`. Each cycle
//!    bounds one face, with the face on its left; cycles of positive signed area are the
//!    bounded faces (counter-clockwise), cycles of negative area are the outer boundaries of
//!    connected components (the outer face) and are dropped.
//! 5. **Assignment**: each building goes wholly to the face containing its footprint's
//!    interior point (`geo::InteriorPoint`, always inside the footprint, unlike the
//!    centroid); faces are looked up through an `rstar` tree of their boxes, and when faces
//!    nest (a street network inside a ring road with no connecting street), the smallest
//!    containing face wins. A building crossing a street therefore goes to one block only.
//!
//! **Leftovers** (a documented citywalk decision): buildings in no bounded face (outside the
//! street network, or in a city without block-bounding streets at all) are grouped by a grid of
//! square cells of [`BlockParams::leftover_cell_m`] (100 m, about one city block), one block
//! per non-empty cell. Nothing is dropped. Once the cluster tree's first cut is available to
//! this stage, a city without streets could use it instead; today it uses the grid.

use std::collections::{BTreeMap, BTreeSet};

use citywalk_scenes::blocks::{UrbanBlock, UrbanBlocks};
use citywalk_scenes::{BuildingId, City, Street, StreetClass};
use geo::{Area, Coord, InteriorPoint, Intersects, LineString, Point, Polygon};
use rayon::prelude::*;
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{AABB, RTree};
use serde::{Deserialize, Serialize};

/// Parameters of the block construction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlockParams {
    /// Street vertices closer than about this are merged into one graph vertex (metres).
    pub snap_tolerance_m: f64,
    /// Side of the grid cells that group buildings outside every street face (metres).
    pub leftover_cell_m: f64,
    /// Whether pedestrian ways (OSM `highway=pedestrian|footway|path|steps|cycleway`) bound
    /// blocks too, besides the classes of
    /// [`StreetClass::bounds_blocks`](citywalk_scenes::StreetClass::bounds_blocks).
    pub pedestrian_bounds_blocks: bool,
}

impl Default for BlockParams {
    fn default() -> Self {
        BlockParams {
            snap_tolerance_m: 0.01,
            leftover_cell_m: 100.0,
            pedestrian_bounds_blocks: false,
        }
    }
}

/// What the block construction found.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BlockReport {
    /// Street segments of block-bounding classes fed to the noding.
    pub street_segments: usize,
    /// Vertices and edges of the planar graph after noding (before pruning).
    pub graph_vertices: usize,
    pub graph_edges: usize,
    /// Edges removed as dangling.
    pub dangling_edges_removed: usize,
    /// Bounded faces of the street graph.
    pub faces: usize,
    /// Blocks that are street faces (faces holding at least one building).
    pub street_blocks: usize,
    /// Blocks that are leftover grid cells.
    pub leftover_blocks: usize,
    /// Buildings in no street face.
    pub leftover_buildings: usize,
}

/// Builds the urban blocks of `city` with the default [`BlockParams`].
pub fn build_blocks(city: &City) -> UrbanBlocks {
    build_blocks_with(city, &BlockParams::default()).0
}

/// Builds the urban blocks of `city`: street faces holding buildings first (in face order),
/// then leftover grid cells (in cell order). Every building is in exactly one block.
pub fn build_blocks_with(city: &City, params: &BlockParams) -> (UrbanBlocks, BlockReport) {
    let mut report = BlockReport::default();
    let faces = street_faces(&city.streets, params, &mut report);
    report.faces = faces.len();

    let face_tree = RTree::bulk_load(
        faces
            .iter()
            .enumerate()
            .filter_map(|(i, f)| {
                let r = geo::BoundingRect::bounding_rect(&f.polygon)?;
                Some(GeomWithData::new(
                    Rectangle::from_corners([r.min().x, r.min().y], [r.max().x, r.max().y]),
                    i,
                ))
            })
            .collect(),
    );

    let mut face_buildings: Vec<Vec<BuildingId>> = vec![Vec::new(); faces.len()];
    let mut leftovers: BTreeMap<(i64, i64), Vec<BuildingId>> = BTreeMap::new();
    let cell_m = if params.leftover_cell_m.is_finite() && params.leftover_cell_m > 0.0 {
        params.leftover_cell_m
    } else {
        BlockParams::default().leftover_cell_m
    };
    // A building's face needs no other building: located on every thread, then filed in
    // building order (the same blocks on any number of threads).
    let located: Vec<(Option<usize>, Point<f64>)> = city
        .buildings
        .par_iter()
        .map(|b| {
            let p = representative_point(b);
            let face = face_tree
                .locate_all_at_point([p.x(), p.y()])
                .map(|g| g.data)
                .filter(|&i| faces[i].polygon.intersects(&p))
                .min_by(|&a, &b| {
                    faces[a]
                        .area_m2
                        .total_cmp(&faces[b].area_m2)
                        .then(a.cmp(&b))
                });
            (face, p)
        })
        .collect();
    for (b, (face, p)) in city.buildings.iter().zip(located) {
        match face {
            Some(i) => face_buildings[i].push(b.id),
            None => {
                let cell = (
                    (p.x() / cell_m).floor() as i64,
                    (p.y() / cell_m).floor() as i64,
                );
                leftovers.entry(cell).or_default().push(b.id);
            }
        }
    }

    let mut blocks = UrbanBlocks {
        blocks: Vec::new(),
        block_of_building: vec![0; city.buildings.len()],
    };
    for (face, buildings) in faces.into_iter().zip(face_buildings) {
        if !buildings.is_empty() {
            push_block(&mut blocks, city, Some(face.polygon), buildings);
            report.street_blocks += 1;
        }
    }
    for (_, buildings) in leftovers {
        report.leftover_buildings += buildings.len();
        report.leftover_blocks += 1;
        push_block(&mut blocks, city, None, buildings);
    }
    (blocks, report)
}

/// A point certainly inside the building's footprint (falls back to the box centre for a
/// degenerate footprint).
fn representative_point(b: &citywalk_scenes::Building) -> Point<f64> {
    b.footprint.interior_point().unwrap_or_else(|| {
        let (lo, hi) = b.bounds();
        Point::new(0.5 * f64::from(lo.x + hi.x), 0.5 * f64::from(lo.y + hi.y))
    })
}

fn push_block(
    blocks: &mut UrbanBlocks,
    city: &City,
    outline: Option<Polygon<f64>>,
    buildings: Vec<BuildingId>,
) {
    let index = blocks.blocks.len() as u32;
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for id in &buildings {
        blocks.block_of_building[id.index()] = index;
        let (blo, bhi) = city.buildings[id.index()].bounds();
        for axis in 0..3 {
            lo[axis] = lo[axis].min(blo[axis]);
            hi[axis] = hi[axis].max(bhi[axis]);
        }
    }
    blocks.blocks.push(UrbanBlock {
        outline,
        buildings,
        bounds_min: lo,
        bounds_max: hi,
    });
}

/// One bounded face of the street graph.
#[derive(Debug, Clone, PartialEq)]
pub struct StreetFace {
    /// Counter-clockwise outline (may touch itself along bridges between cycles).
    pub polygon: Polygon<f64>,
    pub area_m2: f64,
}

/// The bounded faces of the graph of block-bounding streets (see the module documentation).
pub fn street_faces(
    streets: &[Street],
    params: &BlockParams,
    report: &mut BlockReport,
) -> Vec<StreetFace> {
    let segments = block_segments(streets, params.pedestrian_bounds_blocks);
    report.street_segments = segments.len();
    if segments.is_empty() {
        return Vec::new();
    }
    let splits = node_segments(&segments);
    let tol = if params.snap_tolerance_m.is_finite() && params.snap_tolerance_m > 0.0 {
        params.snap_tolerance_m
    } else {
        BlockParams::default().snap_tolerance_m
    };
    let graph = PlanarGraph::build(&segments, splits, tol);
    report.graph_vertices = graph.vertices.len();
    report.graph_edges = graph.edges.len();
    let (graph, removed) = graph.prune_dangling();
    report.dangling_edges_removed = removed;
    graph.bounded_faces()
}

type Seg = ([f64; 2], [f64; 2]);

/// Segments of block-bounding streets, finite and of non-zero length.
fn block_segments(streets: &[Street], pedestrian: bool) -> Vec<Seg> {
    streets
        .iter()
        .filter(|s| s.class.bounds_blocks() || (pedestrian && s.class == StreetClass::Pedestrian))
        .flat_map(|s| s.line.lines())
        .map(|l| ([l.start.x, l.start.y], [l.end.x, l.end.y]))
        .filter(|(a, b)| a.iter().chain(b).all(|v| v.is_finite() && v.abs() < 1e9) && a != b)
        .collect()
}

fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    robust::orient2d(
        robust::Coord { x: a[0], y: a[1] },
        robust::Coord { x: b[0], y: b[1] },
        robust::Coord { x: c[0], y: c[1] },
    )
}

/// Whether `p`, collinear with `a b`, lies within the segment's box.
fn within_box(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> bool {
    (0..2).all(|k| a[k].min(b[k]) <= p[k] && p[k] <= a[k].max(b[k]))
}

/// For each segment, the points where it must be split (its own endpoints included).
fn node_segments(segments: &[Seg]) -> Vec<Vec<[f64; 2]>> {
    let mut splits: Vec<Vec<[f64; 2]>> = segments.iter().map(|&(a, b)| vec![a, b]).collect();
    let tree = RTree::bulk_load(
        segments
            .iter()
            .enumerate()
            .map(|(i, &(a, b))| GeomWithData::new(Rectangle::from_corners(a, b), i))
            .collect(),
    );
    for (i, &(a, b)) in segments.iter().enumerate() {
        let envelope = AABB::from_corners(a, b);
        for other in tree.locate_in_envelope_intersecting(envelope) {
            let j = other.data;
            if j <= i {
                continue;
            }
            let (c, d) = segments[j];
            let o1 = orient(a, b, c);
            let o2 = orient(a, b, d);
            let o3 = orient(c, d, a);
            let o4 = orient(c, d, b);
            if (o1 > 0.0 && o2 > 0.0) || (o1 < 0.0 && o2 < 0.0) {
                continue;
            }
            if (o3 > 0.0 && o4 > 0.0) || (o3 < 0.0 && o4 < 0.0) {
                continue;
            }
            if o1 == 0.0 && o2 == 0.0 {
                // Collinear: each endpoint lying on the other segment splits it.
                for p in [c, d] {
                    if within_box(a, b, p) {
                        splits[i].push(p);
                    }
                }
                for p in [a, b] {
                    if within_box(c, d, p) {
                        splits[j].push(p);
                    }
                }
                continue;
            }
            if o1 == 0.0 {
                splits[i].push(c);
            }
            if o2 == 0.0 {
                splits[i].push(d);
            }
            if o3 == 0.0 {
                splits[j].push(a);
            }
            if o4 == 0.0 {
                splits[j].push(b);
            }
            if o1 != 0.0 && o2 != 0.0 && o3 != 0.0 && o4 != 0.0 {
                // Proper crossing: the point of c d at zero signed distance from a b.
                let t = o1 / (o1 - o2);
                let p = [c[0] + (d[0] - c[0]) * t, c[1] + (d[1] - c[1]) * t];
                splits[i].push(p);
                splits[j].push(p);
            }
        }
    }
    splits
}

/// An undirected planar graph on snapped vertices.
#[derive(Debug)]
struct PlanarGraph {
    /// Snapped positions (metres).
    vertices: Vec<[f64; 2]>,
    /// Undirected edges `(low, high)` in ascending order.
    edges: BTreeSet<(u32, u32)>,
}

impl PlanarGraph {
    fn build(segments: &[Seg], splits: Vec<Vec<[f64; 2]>>, tol: f64) -> PlanarGraph {
        let mut ids: BTreeMap<(i64, i64), u32> = BTreeMap::new();
        let mut vertices = Vec::new();
        let mut edges = BTreeSet::new();
        for (&(a, b), mut points) in segments.iter().zip(splits) {
            let dir = [b[0] - a[0], b[1] - a[1]];
            let param = |p: &[f64; 2]| (p[0] - a[0]) * dir[0] + (p[1] - a[1]) * dir[1];
            points.sort_by(|p, q| param(p).total_cmp(&param(q)));
            let mut previous: Option<u32> = None;
            for p in points {
                let key = ((p[0] / tol).round() as i64, (p[1] / tol).round() as i64);
                let id = *ids.entry(key).or_insert_with(|| {
                    vertices.push([key.0 as f64 * tol, key.1 as f64 * tol]);
                    (vertices.len() - 1) as u32
                });
                if let Some(prev) = previous
                    && prev != id
                {
                    edges.insert((prev.min(id), prev.max(id)));
                }
                previous = Some(id);
            }
        }
        PlanarGraph { vertices, edges }
    }

    /// Removes dangling edges repeatedly until every vertex has degree 0 or at least 2.
    fn prune_dangling(mut self) -> (PlanarGraph, usize) {
        let mut adjacency: Vec<BTreeSet<u32>> = vec![BTreeSet::new(); self.vertices.len()];
        for &(u, v) in &self.edges {
            adjacency[u as usize].insert(v);
            adjacency[v as usize].insert(u);
        }
        let mut stack: Vec<u32> = (0..self.vertices.len() as u32)
            .filter(|&v| adjacency[v as usize].len() == 1)
            .collect();
        let mut removed = 0;
        while let Some(v) = stack.pop() {
            let Some(&u) = adjacency[v as usize].iter().next() else {
                continue;
            };
            if adjacency[v as usize].len() != 1 {
                continue;
            }
            adjacency[v as usize].clear();
            adjacency[u as usize].remove(&v);
            self.edges.remove(&(u.min(v), u.max(v)));
            removed += 1;
            if adjacency[u as usize].len() == 1 {
                stack.push(u);
            }
        }
        (self, removed)
    }

    /// The planar-face traversal (module documentation, step 4).
    fn bounded_faces(&self) -> Vec<StreetFace> {
        // Half-edge 2k is edge k low → high, 2k + 1 its twin.
        let edges: Vec<(u32, u32)> = self.edges.iter().copied().collect();
        let origin = |h: usize| -> u32 {
            let (u, v) = edges[h / 2];
            if h.is_multiple_of(2) { u } else { v }
        };
        let target = |h: usize| origin(h ^ 1);
        let mut outgoing: Vec<Vec<usize>> = vec![Vec::new(); self.vertices.len()];
        for h in 0..2 * edges.len() {
            outgoing[origin(h) as usize].push(h);
        }
        let angle = |h: usize| {
            let p = self.vertices[origin(h) as usize];
            let q = self.vertices[target(h) as usize];
            (q[1] - p[1]).atan2(q[0] - p[0])
        };
        let mut position = vec![0usize; 2 * edges.len()];
        for list in &mut outgoing {
            list.sort_by(|&g, &h| angle(g).total_cmp(&angle(h)).then(g.cmp(&h)));
            for (k, &h) in list.iter().enumerate() {
                position[h] = k;
            }
        }
        let next = |h: usize| -> usize {
            let twin = h ^ 1;
            let around = &outgoing[origin(twin) as usize];
            around[(position[twin] + around.len() - 1) % around.len()]
        };

        let mut visited = vec![false; 2 * edges.len()];
        let mut faces = Vec::new();
        for start in 0..2 * edges.len() {
            if visited[start] {
                continue;
            }
            let mut ring: Vec<Coord<f64>> = Vec::new();
            let mut h = start;
            while !visited[h] {
                visited[h] = true;
                let p = self.vertices[origin(h) as usize];
                ring.push(Coord { x: p[0], y: p[1] });
                h = next(h);
            }
            if ring.len() < 3 {
                continue;
            }
            let polygon = Polygon::new(LineString::new(ring), Vec::new());
            let signed = polygon.signed_area();
            if signed > 0.0 {
                faces.push(StreetFace {
                    polygon,
                    area_m2: signed,
                });
            }
        }
        faces
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use citywalk_scenes::{Building, BuildingPart, Frame, HeightSource, LoadReport, StreetClass};
    use geo::{MultiPolygon, polygon};

    fn street(class: StreetClass, points: &[(f64, f64)]) -> Street {
        Street {
            source_id: "s".into(),
            class,
            name: None,
            line: LineString::from(points.to_vec()),
            tagged_width_m: None,
        }
    }

    fn building(i: u32, x0: f64, y0: f64, x1: f64, y1: f64) -> Building {
        let footprint = MultiPolygon::new(vec![polygon![
            (x: x0, y: y0), (x: x1, y: y0), (x: x1, y: y1), (x: x0, y: y1)
        ]]);
        Building {
            id: BuildingId(i),
            source_id: format!("b{i}"),
            footprint: footprint.clone(),
            parts: vec![BuildingPart {
                source_id: format!("b{i}"),
                footprint,
                base_m: 0.0,
                top_m: 10.0,
            }],
            base_m: 0.0,
            top_m: 10.0,
            height_source: HeightSource::Tagged,
            mesh: None,
            tags: Default::default(),
        }
    }

    /// Four streets each way, 100 m apart, overshooting the grid by 20 m (dangling ends),
    /// plus a footway through the middle that must not split blocks.
    fn grid_city() -> City {
        let mut streets = Vec::new();
        for k in 0..4 {
            let c = k as f64 * 100.0;
            streets.push(street(StreetClass::Residential, &[(-20.0, c), (320.0, c)]));
            // Vertical streets in two pieces, joined at y = 150 (not a crossing).
            streets.push(street(StreetClass::Minor, &[(c, -20.0), (c, 150.0)]));
            streets.push(street(StreetClass::Minor, &[(c, 150.0), (c, 320.0)]));
        }
        streets.push(street(
            StreetClass::Pedestrian,
            &[(0.0, 50.0), (300.0, 50.0)],
        ));
        let mut buildings = Vec::new();
        let mut i = 0;
        for bx in 0..3 {
            for by in 0..3 {
                let (x, y) = (bx as f64 * 100.0, by as f64 * 100.0);
                buildings.push(building(i, x + 10.0, y + 10.0, x + 40.0, y + 40.0));
                i += 1;
                buildings.push(building(i, x + 60.0, y + 60.0, x + 90.0, y + 90.0));
                i += 1;
            }
        }
        // Crossing the street x = 100 between blocks (0,0) and (1,0): mostly in (1,0).
        buildings.push(building(i, 95.0, 20.0, 130.0, 30.0));
        i += 1;
        // Outside the grid entirely.
        buildings.push(building(i, 500.0, 500.0, 510.0, 510.0));
        City {
            frame: Frame::local(),
            buildings,
            streets,
            ground_areas: Vec::new(),
            report: LoadReport::default(),
        }
    }

    #[test]
    fn a_three_by_three_grid_gives_nine_blocks_and_the_right_assignment() {
        let city = grid_city();
        let (blocks, report) = build_blocks_with(&city, &BlockParams::default());
        assert_eq!(blocks.check_invariants(city.buildings.len()), Ok(()));
        assert_eq!(report.faces, 9, "{report:?}");
        assert_eq!(report.street_blocks, 9);
        assert!(report.dangling_edges_removed >= 12, "{report:?}");
        assert_eq!(report.leftover_blocks, 1);
        assert_eq!(blocks.blocks.len(), 10);
        // Buildings 2k and 2k+1 are in the same grid cell, and only they (plus the crossing one).
        for k in 0..9 {
            let a = blocks.block_of_building[2 * k];
            assert_eq!(a, blocks.block_of_building[2 * k + 1]);
            let outline = blocks.blocks[a as usize]
                .outline
                .as_ref()
                .expect("street block");
            let area = outline.unsigned_area();
            assert!((area - 10_000.0).abs() < 1.0, "block area {area}");
            let (bx, by) = ((k / 3) as f64 * 100.0, (k % 3) as f64 * 100.0);
            let r = geo::BoundingRect::bounding_rect(outline).expect("rect");
            assert!((r.min().x - bx).abs() < 0.02 && (r.min().y - by).abs() < 0.02);
        }
        // The crossing building goes wholly to the block holding most of it.
        let crossing = blocks.block_of_building[18];
        assert_eq!(crossing, blocks.block_of_building[2 * 3]);
        let outside = blocks.block_of_building[19];
        assert!(blocks.blocks[outside as usize].outline.is_none());
        assert_eq!(
            blocks.blocks[outside as usize].buildings,
            vec![BuildingId(19)]
        );
    }

    #[test]
    fn pedestrian_ways_bound_blocks_only_when_asked() {
        // The footway at y = 50 runs through the bottom row: with the option, each of its
        // three blocks splits in two, and the buildings below and above it part.
        let city = grid_city();
        let params = BlockParams {
            pedestrian_bounds_blocks: true,
            ..BlockParams::default()
        };
        let (blocks, report) = build_blocks_with(&city, &params);
        assert_eq!(blocks.check_invariants(city.buildings.len()), Ok(()));
        assert_eq!(report.faces, 12, "{report:?}");
        for k in [0, 3, 6] {
            assert_ne!(
                blocks.block_of_building[2 * k],
                blocks.block_of_building[2 * k + 1],
                "cell {k}"
            );
        }
        let (default, _) = build_blocks_with(&city, &BlockParams::default());
        assert_eq!(default.block_of_building[0], default.block_of_building[1]);
    }

    #[test]
    fn a_city_without_streets_falls_back_to_grid_cells() {
        let mut city = grid_city();
        city.streets.clear();
        let (blocks, report) = build_blocks_with(&city, &BlockParams::default());
        assert_eq!(blocks.check_invariants(city.buildings.len()), Ok(()));
        assert_eq!(report.faces, 0);
        assert_eq!(report.leftover_buildings, city.buildings.len());
        assert!(blocks.blocks.iter().all(|b| b.outline.is_none()));
        // Cells of 100 m: the two buildings of a grid cell share a cell.
        for k in 0..9 {
            assert_eq!(
                blocks.block_of_building[2 * k],
                blocks.block_of_building[2 * k + 1]
            );
        }
    }

    /// Random streets inside a ring road, all crossing one spanning avenue each way (so the
    /// street graph is connected and faces do not nest): the faces must tile without overlap (their areas add
    /// up to the area of their union) and every random building lands in exactly one block.
    #[test]
    fn random_street_networks_give_non_overlapping_faces() {
        use proptest::prelude::*;
        use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
        let segment = (0.0f64..400.0, 0.0f64..400.0, 0.0f64..400.0, 0.0f64..400.0);
        let strategy = (
            prop::collection::vec(segment, 2..14),
            prop::collection::vec((0.0f64..400.0, 0.0f64..400.0), 0..40),
        );
        let mut runner = TestRunner::new_with_rng(
            Config {
                cases: 48,
                failure_persistence: None,
                ..Config::default()
            },
            TestRng::from_seed(RngAlgorithm::ChaCha, &[11; 32]),
        );
        runner
            .run(&strategy, |(segments, spots)| {
                let mut streets = vec![
                    street(
                        StreetClass::Major,
                        &[
                            (-5.0, -5.0),
                            (405.0, -5.0),
                            (405.0, 405.0),
                            (-5.0, 405.0),
                            (-5.0, -5.0),
                        ],
                    ),
                    street(StreetClass::Major, &[(-10.0, 200.0), (410.0, 200.0)]),
                    street(StreetClass::Major, &[(200.0, -10.0), (200.0, 410.0)]),
                ];
                for (x0, y0, x1, y1) in segments {
                    // Extend each street across the spanning avenues' square so it meets them.
                    let dir = [x1 - x0, y1 - y0];
                    let len = (dir[0] * dir[0] + dir[1] * dir[1]).sqrt().max(1e-3);
                    let (ux, uy) = (dir[0] / len * 600.0, dir[1] / len * 600.0);
                    streets.push(street(
                        StreetClass::Residential,
                        &[(x0 - ux, y0 - uy), (x0 + ux, y0 + uy)],
                    ));
                }
                let mut report = BlockReport::default();
                let faces = street_faces(&streets, &BlockParams::default(), &mut report);
                prop_assert!(faces.len() >= 4, "{report:?}");
                let total: f64 = faces.iter().map(|f| f.area_m2).sum();
                let union = geo::unary_union(faces.iter().map(|f| &f.polygon)).unsigned_area();
                prop_assert!(
                    (total - union).abs() <= 1e-6 * union.max(1.0) + 1e-3,
                    "faces overlap: sum {total} vs union {union}"
                );
                let buildings: Vec<Building> = spots
                    .iter()
                    .enumerate()
                    .map(|(i, &(x, y))| building(i as u32, x, y, x + 3.0, y + 2.0))
                    .collect();
                let city = City {
                    frame: Frame::local(),
                    buildings,
                    streets,
                    ground_areas: Vec::new(),
                    report: LoadReport::default(),
                };
                let (blocks, _) = build_blocks_with(&city, &BlockParams::default());
                prop_assert_eq!(blocks.check_invariants(city.buildings.len()), Ok(()));
                Ok(())
            })
            .expect("random street networks");
    }

    #[test]
    fn crossing_streets_without_shared_vertices_are_noded() {
        // A square ring crossed by a diagonal street: 2 faces... plus the crossing forms them.
        let streets = vec![
            street(
                StreetClass::Major,
                &[
                    (0.0, 0.0),
                    (10.0, 0.0),
                    (10.0, 10.0),
                    (0.0, 10.0),
                    (0.0, 0.0),
                ],
            ),
            street(StreetClass::Major, &[(-5.0, -5.0), (15.0, 15.0)]),
        ];
        let mut report = BlockReport::default();
        let faces = street_faces(&streets, &BlockParams::default(), &mut report);
        assert_eq!(faces.len(), 2, "{report:?}");
        let total: f64 = faces.iter().map(|f| f.area_m2).sum();
        assert!((total - 100.0).abs() < 1e-6);
        for f in &faces {
            assert!((f.area_m2 - 50.0).abs() < 1e-6);
        }
    }
}
