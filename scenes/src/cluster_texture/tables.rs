//! The tables the runtime's textured scene pass reads (`wgsl/shared/cluster_textures.wgsl`): per cluster
//! tree node where its textures lie, per wall of a textured cluster mesh its hull edge and its
//! image in the side view. Built once at load from the package's atlas layout and the cluster
//! meshes in the GPU scene's arrays, which are checked against the layout: a package is
//! untrusted input, and a mesh that is not the extruded hull the layout describes is drawn in
//! flat colours, with the reason, rather than sampled wrongly.

use super::atlas::{AtlasLayout, ClusterPlacement};
use citywalk_shaders::constants::NO_TEXTURE_PAGE;
use citywalk_shaders::{BuildingRecord, SceneVertex, TexturedCluster, TexturedWall};

/// The scene's arrays the tables are read from: every draw id's record (buildings first, then
/// tree node `n` at `building_count + n`), the vertices and the indices.
#[derive(Debug, Clone, Copy)]
pub struct MeshArrays<'a> {
    pub building_count: u32,
    pub node_count: u32,
    pub records: &'a [BuildingRecord],
    pub vertices: &'a [SceneVertex],
    pub indices: &'a [u32],
}

/// The textured scene pass's tables.
#[derive(Debug, Clone, PartialEq)]
pub struct TextureTables {
    /// One per tree node (at least one, untextured, so the buffer is never empty).
    pub clusters: Vec<TexturedCluster>,
    pub walls: Vec<TexturedWall>,
    /// Clusters the layout places but the tables leave untextured: (node, reason).
    pub rejected: Vec<(u32, String)>,
}

impl TextureTables {
    /// The tables of `layout` over `meshes`.
    pub fn build(layout: &AtlasLayout, meshes: MeshArrays<'_>) -> TextureTables {
        let untextured = TexturedCluster {
            page: NO_TEXTURE_PAGE,
            ..TexturedCluster::default()
        };
        let mut tables = TextureTables {
            clusters: vec![untextured; meshes.node_count.max(1) as usize],
            walls: Vec::new(),
            rejected: Vec::new(),
        };
        for placement in &layout.clusters {
            let node = placement.node;
            match cluster_entry(layout, placement, meshes, tables.walls.len()) {
                Ok((cluster, walls)) => {
                    tables.clusters[node as usize] = cluster;
                    tables.walls.extend(walls);
                }
                Err(reason) => tables.rejected.push((node, reason)),
            }
        }
        tables
    }

    /// Clusters drawn with textures.
    pub fn textured(&self) -> usize {
        self.clusters
            .iter()
            .filter(|c| c.page != NO_TEXTURE_PAGE)
            .count()
    }
}

/// The table entries of one placed cluster, its walls numbered from `first_wall`.
fn cluster_entry(
    layout: &AtlasLayout,
    placement: &ClusterPlacement,
    meshes: MeshArrays<'_>,
    first_wall: usize,
) -> Result<(TexturedCluster, Vec<TexturedWall>), String> {
    let node = placement.node;
    if node >= meshes.node_count {
        return Err(format!("no tree node {node}"));
    }
    let bin = layout
        .bins
        .get(placement.bin as usize)
        .ok_or_else(|| format!("no bin {}", placement.bin))?;
    if placement.page >= layout.page_count {
        return Err(format!("no page {}", placement.page));
    }
    let draw_id = meshes.building_count as usize + node as usize;
    let record = meshes
        .records
        .get(draw_id)
        .ok_or_else(|| format!("no record for draw id {draw_id}"))?;
    let n = placement.sides.faces.len();
    let ring = hull_ring(record, meshes, n)?;
    let walls = (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len2 = d[0] * d[0] + d[1] * d[1];
            let along_per_m = if len2 > 0.0 {
                [d[0] / len2, d[1] / len2]
            } else {
                [0.0, 0.0]
            };
            let r = placement
                .face_rect_px(bin, i)
                .expect("a face per wall: n is the face count");
            TexturedWall {
                start_m: a,
                along_per_m,
                rect_px: [r.x_px, r.y_px, r.width_px, r.height_px].map(|v| v as f32),
            }
        })
        .collect::<Vec<_>>();
    let roof = placement.roof_rect_px(bin);
    let [lo, hi] = [placement.box_lo_m, placement.box_hi_m];
    let cluster = TexturedCluster {
        base_vertex: record.base_vertex as u32,
        first_wall: u32::try_from(first_wall).map_err(|_| "over 2^32 walls".to_string())?,
        wall_count: n as u32,
        page: placement.page,
        roof_rect_px: [roof.x_px, roof.y_px, roof.width_px, roof.height_px].map(|v| v as f32),
        box_lo_m: [lo[0], lo[1], lo[2], placement.bin as f32],
        box_hi_m: [hi[0], hi[1], hi[2], 0.0],
    };
    Ok((cluster, walls))
}

/// The hull ring (x, y per wall's first vertex) of a cluster mesh of `n` walls, checked to be
/// laid out as `citywalk_scenes::extrude::extruded_walls` reads it: a foot and a top vertex per
/// ring vertex, wall `i`'s two triangles first, each starting at its foot `2i` (the vertex
/// the textured pass's flat interpolation takes).
fn hull_ring(
    record: &BuildingRecord,
    meshes: MeshArrays<'_>,
    n: usize,
) -> Result<Vec<[f32; 2]>, String> {
    let not_hull = |why: &str| Err(format!("the mesh is not the layout's extruded hull: {why}"));
    if n < 3 || record.vertex_count as usize != 2 * n || (record.index_count as usize) < 6 * n {
        return not_hull(&format!(
            "{} vertices and {} indices for {n} walls",
            record.vertex_count, record.index_count
        ));
    }
    let (Ok(base), Ok(first)) = (
        usize::try_from(record.base_vertex),
        usize::try_from(record.first_index),
    ) else {
        return not_hull("a negative base vertex");
    };
    let (Some(vertices), Some(indices)) = (
        meshes.vertices.get(base..base + 2 * n),
        meshes.indices.get(first..first + 6 * n),
    ) else {
        return not_hull("its ranges lie outside the scene's arrays");
    };
    for (i, wall) in indices.chunks_exact(6).enumerate() {
        let (a, b) = (2 * i as u32, 2 * ((i + 1) % n) as u32);
        if wall != [a, b, b + 1, a, b + 1, a + 1] {
            return not_hull(&format!("wall {i}'s triangles"));
        }
    }
    Ok(vertices
        .chunks_exact(2)
        .map(|foot_top| [foot_top[0].position_m[0], foot_top[0].position_m[1]])
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster_texture::atlas::{ClusterWalls, layout_atlas};
    use crate::cluster_texture::roof_views::RoofView;
    use crate::extrude::{extrude_polygon, extruded_walls};
    use crate::scene_geometry::SceneGeometry;
    use geo::polygon;
    use glam::Vec3;
    use std::borrow::Cow;

    /// Two cluster meshes (tree nodes 0 and 1) after one building, extruded hulls of 4 and 5
    /// walls, laid out in pages of `page_px`.
    fn scene(page_px: u32) -> (SceneGeometry, AtlasLayout) {
        let square =
            polygon![(x: 0.0, y: 0.0), (x: 40.0, y: 0.0), (x: 40.0, y: 30.0), (x: 0.0, y: 30.0)];
        let pentagon = polygon![(x: 100.0, y: 0.0), (x: 140.0, y: 0.0), (x: 150.0, y: 20.0), (x: 120.0, y: 40.0), (x: 95.0, y: 20.0)];
        let meshes = [
            extrude_polygon(&building_polygon(), 0.0, 8.0),
            extrude_polygon(&square, 0.0, 12.0),
            extrude_polygon(&pentagon, 2.0, 20.0),
        ];
        let geometry = SceneGeometry::from_mesh_iter(
            meshes
                .iter()
                .map(|m| (Cow::Borrowed(m), m.bounds().expect("non-empty"))),
            1,
        );
        let walls = meshes[1..]
            .iter()
            .enumerate()
            .map(|(node, mesh)| {
                let (ring, base_m, top_m) = extruded_walls(mesh).expect("a hull");
                ClusterWalls {
                    node: node as u32,
                    negative_space_m2: node as f64,
                    ring,
                    base_m,
                    top_m,
                }
            })
            .collect::<Vec<_>>();
        (geometry, layout_atlas(&walls, page_px))
    }

    fn building_polygon() -> geo::Polygon<f64> {
        polygon![(x: 0.0, y: 0.0), (x: 5.0, y: 0.0), (x: 5.0, y: 5.0)]
    }

    fn arrays(g: &SceneGeometry) -> MeshArrays<'_> {
        MeshArrays {
            building_count: 1,
            node_count: 2,
            records: &g.records,
            vertices: &g.vertices,
            indices: &g.indices,
        }
    }

    /// The continuous texel the shader computes for a wall point (`wall_texel`).
    fn wall_texel(c: &TexturedCluster, w: &TexturedWall, p: Vec3) -> [f32; 2] {
        let along = ((p.x - w.start_m[0]) * w.along_per_m[0]
            + (p.y - w.start_m[1]) * w.along_per_m[1])
            .clamp(0.0, 1.0);
        let up = ((p.z - c.box_lo_m[2]) / (c.box_hi_m[2] - c.box_lo_m[2])).clamp(0.0, 1.0);
        [
            w.rect_px[0] + along * w.rect_px[2],
            w.rect_px[1] + (1.0 - up) * w.rect_px[3],
        ]
    }

    #[test]
    fn walls_map_to_the_texels_the_layout_gives_them() {
        let (g, layout) = scene(256);
        let tables = TextureTables::build(&layout, arrays(&g));
        assert!(tables.rejected.is_empty(), "{:?}", tables.rejected);
        assert_eq!(tables.textured(), 2);
        assert_eq!(tables.walls.len(), 9);
        for placement in &layout.clusters {
            let c = &tables.clusters[placement.node as usize];
            let bin = &layout.bins[placement.bin as usize];
            let side = placement.sides.side_px as f32;
            let [ox, oy] = bin.cell_origin_px(placement.cell).map(|v| v as f32);
            let record = &g.records[1 + placement.node as usize];
            for (i, w) in tables.walls[c.first_wall as usize..][..c.wall_count as usize]
                .iter()
                .enumerate()
            {
                let v =
                    |k: usize| Vec3::from(g.vertices[record.base_vertex as usize + k].position_m);
                let n = c.wall_count as usize;
                let (a, b) = (v(2 * i), v(2 * ((i + 1) % n)));
                for (along, up) in [(0.0, 0.0), (1.0, 1.0), (0.25, 0.6)] {
                    let z = c.box_lo_m[2] + up * (c.box_hi_m[2] - c.box_lo_m[2]);
                    let p = a.lerp(b, along).with_z(z);
                    let got = wall_texel(c, w, p);
                    let [u, v] = placement.sides.uv(i, along, up);
                    let want = [ox + u * side, oy + v * side];
                    assert!(
                        (got[0] - want[0]).abs() < 1e-3 && (got[1] - want[1]).abs() < 1e-3,
                        "node {} wall {i} at ({along}, {up}): {got:?}, layout {want:?}",
                        placement.node
                    );
                }
            }
            // The roof rectangle and box are the layout's: the shader's roof_texel maps a roof
            // point as ClusterPlacement::roof_uv does (checked on the GPU).
            let corner = Vec3::from(placement.box_lo_m).with_z(placement.box_hi_m[2]);
            let [u, v] = placement.roof_uv(bin, layout.page_px, RoofView::Top, corner);
            let page = layout.page_px as f32;
            let r = c.roof_rect_px;
            assert!((u * page - r[0]).abs() < 1e-3, "{u} {r:?}");
            assert!((v * page - (r[1] + r[3])).abs() < 1e-3, "{v} {r:?}");
        }
    }

    #[test]
    fn a_mesh_the_layout_does_not_describe_stays_untextured() {
        let (mut g, layout) = scene(256);
        // Node 1's third wall, its triangles swapped: the provoking vertex is no longer 2i.
        let r = g.records[2];
        let first = r.first_index as usize + 12;
        g.indices[first..first + 6].rotate_left(3);
        let tables = TextureTables::build(&layout, arrays(&g));
        assert_eq!(tables.textured(), 1);
        assert_eq!(tables.rejected.len(), 1);
        assert_eq!(tables.rejected[0].0, 1);
        assert!(
            tables.rejected[0].1.contains("wall 2"),
            "{:?}",
            tables.rejected
        );
        assert_eq!(tables.clusters[1].page, NO_TEXTURE_PAGE);
        // A layout naming nodes the scene does not have: rejected, nothing read out of range.
        let tables = TextureTables::build(
            &layout,
            MeshArrays {
                node_count: 1,
                records: &g.records[..2],
                ..arrays(&g)
            },
        );
        assert_eq!(tables.textured(), 1);
        assert!(tables.rejected[0].1.contains("no tree node 1"));
    }
}
