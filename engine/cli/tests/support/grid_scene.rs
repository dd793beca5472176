//! The scene file the binary-driving tests share.

use std::path::Path;

/// A 3 × 3 grid of buildings (30 m squares, 9 to 33 m tall) separated by 20 m streets, with the
/// street centre lines, in local metres, as GeoJSON.
pub fn write_scene(path: &Path) {
    let mut features = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            let (x, y) = (f64::from(i) * 50.0, f64::from(j) * 50.0);
            let ring = [
                [x, y],
                [x + 30.0, y],
                [x + 30.0, y + 30.0],
                [x, y + 30.0],
                [x, y],
            ];
            features.push(serde_json::json!({
                "type": "Feature",
                "id": format!("b{i}{j}"),
                "properties": { "building": "yes", "height": 9.0 + 3.0 * f64::from(i * 3 + j) },
                "geometry": { "type": "Polygon", "coordinates": [ring] }
            }));
        }
    }
    for k in 0..4 {
        let c = f64::from(k) * 50.0 - 10.0;
        for line in [[[-20.0, c], [150.0, c]], [[c, -20.0], [c, 150.0]]] {
            features.push(serde_json::json!({
                "type": "Feature",
                "properties": { "highway": "residential" },
                "geometry": { "type": "LineString", "coordinates": line }
            }));
        }
    }
    let scene = serde_json::json!({
        "type": "FeatureCollection",
        "crs": { "type": "name", "properties": { "name": "citywalk:local" } },
        "features": features
    });
    std::fs::write(path, scene.to_string()).expect("write the test scene");
}
