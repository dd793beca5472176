//! Assembly of OSM multipolygon relations: joining member ways into closed rings and
//! placing inner rings in the outer ring that contains them.
//!
//! Follows the OSM multipolygon rules (<https://wiki.openstreetmap.org/wiki/Relation:multipolygon>,
//! "Valid multipolygon conditions"): every ring is closed, and may be split over several ways
//! that share end nodes; a way may run in either direction. Members with role `inner` are holes;
//! any other role (`outer`, or empty as in old data) is an outer ring. Rings are joined on node
//! ids, so the join is exact.

use geo::{Area, Coord, Intersects, LineString, Polygon};

/// Joins ways (node id lists) into closed rings. Fails with a reason naming the node where a
/// ring stays open.
pub fn join_rings(ways: Vec<Vec<i64>>) -> Result<Vec<Vec<i64>>, String> {
    let mut rings = Vec::new();
    let mut pending: Vec<Vec<i64>> = Vec::new();
    for way in ways {
        match (way.first(), way.last()) {
            (Some(a), Some(b)) if a == b && way.len() > 1 => rings.push(way),
            (Some(_), Some(_)) => pending.push(way),
            _ => return Err("member way without nodes".into()),
        }
    }
    while let Some(mut chain) = pending.pop() {
        loop {
            let (Some(&first), Some(&last)) = (chain.first(), chain.last()) else {
                return Err("empty chain".into());
            };
            if first == last {
                rings.push(chain);
                break;
            }
            let next = pending.iter().position(|w| {
                w.first() == Some(&last)
                    || w.last() == Some(&last)
                    || w.first() == Some(&first)
                    || w.last() == Some(&first)
            });
            let Some(j) = next else {
                return Err(format!(
                    "ring open between node/{first} and node/{last} (no member way continues it)"
                ));
            };
            let mut w = pending.swap_remove(j);
            if w.first() == Some(&last) {
                chain.extend_from_slice(&w[1..]);
            } else if w.last() == Some(&last) {
                w.reverse();
                chain.extend_from_slice(&w[1..]);
            } else if w.last() == Some(&first) {
                w.extend_from_slice(&chain[1..]);
                chain = w;
            } else {
                w.reverse();
                w.extend_from_slice(&chain[1..]);
                chain = w;
            }
        }
    }
    Ok(rings)
}

/// Groups coordinate rings into polygons: each inner ring goes into the smallest outer ring that
/// contains one of its points. Returns the polygons and the number of inner rings that lay in
/// no outer ring (dropped).
pub fn group_polygons(
    outers: Vec<Vec<Coord<f64>>>,
    inners: Vec<Vec<Coord<f64>>>,
) -> (Vec<Vec<Vec<Coord<f64>>>>, usize) {
    let shapes: Vec<Polygon<f64>> = outers
        .iter()
        .map(|r| Polygon::new(LineString::new(r.clone()), vec![]))
        .collect();
    let sizes: Vec<f64> = shapes.iter().map(Area::unsigned_area).collect();
    let mut polygons: Vec<Vec<Vec<Coord<f64>>>> = outers.into_iter().map(|r| vec![r]).collect();
    let mut dropped = 0;
    for inner in inners {
        // A vertex of the inner ring may touch the outer ring; the midpoint of its first edge
        // is as good a probe as any and avoids shared nodes.
        let probe = match (inner.first(), inner.get(1)) {
            (Some(a), Some(b)) => geo::Point::new(0.5 * (a.x + b.x), 0.5 * (a.y + b.y)),
            _ => {
                dropped += 1;
                continue;
            }
        };
        let owner = (0..shapes.len())
            .filter(|&i| shapes[i].intersects(&probe))
            .min_by(|&a, &b| sizes[a].total_cmp(&sizes[b]));
        match owner {
            Some(i) => polygons[i].push(inner),
            None => dropped += 1,
        }
    }
    (polygons, dropped)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn joins_split_and_reversed_ways() {
        // A square 1-2-3-4 split into three ways, one reversed, plus a closed triangle.
        let rings = join_rings(vec![
            vec![1, 2],
            vec![4, 3, 2],
            vec![4, 1],
            vec![10, 11, 12, 10],
        ])
        .unwrap();
        assert_eq!(rings.len(), 2);
        let square = rings.iter().find(|r| r.contains(&1)).unwrap();
        assert_eq!(square.len(), 5);
        assert_eq!(square.first(), square.last());
        let mut nodes = square[..4].to_vec();
        nodes.sort_unstable();
        assert_eq!(nodes, vec![1, 2, 3, 4]);
    }

    #[test]
    fn open_ring_is_an_error() {
        let err = join_rings(vec![vec![1, 2, 3], vec![3, 4]]).unwrap_err();
        assert!(err.contains("open"), "{err}");
    }

    #[test]
    fn inner_goes_to_its_outer() {
        let sq = |x0: f64, s: f64| {
            vec![
                Coord { x: x0, y: 0.0 },
                Coord { x: x0 + s, y: 0.0 },
                Coord { x: x0 + s, y: s },
                Coord { x: x0, y: s },
                Coord { x: x0, y: 0.0 },
            ]
        };
        let hole = |x0: f64| {
            vec![
                Coord {
                    x: x0 + 1.0,
                    y: 1.0,
                },
                Coord {
                    x: x0 + 2.0,
                    y: 1.0,
                },
                Coord {
                    x: x0 + 2.0,
                    y: 2.0,
                },
                Coord {
                    x: x0 + 1.0,
                    y: 1.0,
                },
            ]
        };
        let (polys, dropped) = group_polygons(
            vec![sq(0.0, 10.0), sq(20.0, 10.0)],
            vec![hole(20.0), hole(100.0)],
        );
        assert_eq!(dropped, 1);
        assert_eq!(polys[0].len(), 1);
        assert_eq!(polys[1].len(), 2);
    }
}
