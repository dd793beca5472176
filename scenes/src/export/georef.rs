//! Where the exported city stands on the globe: the 3D Tiles root `transform` from the scene's
//! local frame (x east, y north, z up, metres) to earth-centred, earth-fixed metres.
//!
//! For geographic frames (WGS84, ECEF) the local frame is the east-north-up tangent plane at
//! the origin, so the transform is exact. A projected frame's axes are the projection's grid
//! axes, which turn away from true north (grid convergence, ~0.9° in The Hague on RD New) and
//! scale by the projection's factor: the transform's columns are the ECEF images of one metre
//! along each grid axis at the origin, found by projecting points through proj4rs with the EPSG
//! definition, which is exact at the origin and within centimetres over a city. Heights are
//! written as the source gives them, as heights above the WGS84 ellipsoid: a vertical datum
//! such as NAP is not converted (in the Netherlands the geoid is ~43 m above the ellipsoid).

use glam::{DMat4, DVec3, DVec4};
use proj4rs::proj::Proj;

use crate::frame::{Crs, Frame, epsg_code, geodetic_to_ecef};

/// Why the city could not be placed on the globe.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlacementError {
    #[error(
        "the scene has no geographic placement (a procedural city or an input without a CRS): give the longitude and latitude of its origin with --place LON,LAT"
    )]
    NotPlaced,
    #[error("cannot place the projected CRS {crs:?} on the globe: {why}")]
    Projection { crs: String, why: String },
    #[error("--place {lon},{lat}: longitude must be within ±180° and latitude within ±90°")]
    BadPlace { lon: f64, lat: f64 },
}

/// The column-major matrix from the local frame to ECEF metres. A [`Crs::Local`] frame needs
/// `place` (longitude, latitude in degrees of its origin); any other frame ignores it.
pub fn root_transform(frame: &Frame, place: Option<(f64, f64)>) -> Result<DMat4, PlacementError> {
    match &frame.crs {
        Crs::Wgs84 | Crs::Ecef => Ok(enu_to_ecef(
            frame.origin[0],
            frame.origin[1],
            frame.origin[2],
        )),
        Crs::Local => {
            let (lon, lat) = place.ok_or(PlacementError::NotPlaced)?;
            if !(lon.abs() <= 180.0 && lat.abs() <= 90.0) {
                return Err(PlacementError::BadPlace { lon, lat });
            }
            Ok(enu_to_ecef(lon, lat, frame.origin[2]))
        }
        Crs::Projected(name) => projected_to_ecef(name, frame.origin),
    }
}

/// East-north-up at `(lon°, lat°, h)` to ECEF.
fn enu_to_ecef(lon_deg: f64, lat_deg: f64, h: f64) -> DMat4 {
    let (slon, clon) = lon_deg.to_radians().sin_cos();
    let (slat, clat) = lat_deg.to_radians().sin_cos();
    let east = DVec3::new(-slon, clon, 0.0);
    let north = DVec3::new(-slat * clon, -slat * slon, clat);
    let up = DVec3::new(clat * clon, clat * slon, slat);
    let origin = geodetic_to_ecef(lon_deg, lat_deg, h);
    DMat4::from_cols(
        east.extend(0.0),
        north.extend(0.0),
        up.extend(0.0),
        origin.extend(1.0),
    )
}

fn projected_to_ecef(name: &str, origin: [f64; 3]) -> Result<DMat4, PlacementError> {
    let fail = |why: String| PlacementError::Projection {
        crs: name.to_string(),
        why,
    };
    let code = epsg_code(name)
        .and_then(|c| u16::try_from(c).ok())
        .ok_or_else(|| fail("not an EPSG code".into()))?;
    let definition = crs_definitions::from_code(code)
        .ok_or_else(|| fail(format!("EPSG:{code} is not in the EPSG definitions known")))?;
    let source = Proj::from_proj_string(definition.proj4)
        .map_err(|e| fail(format!("its definition does not parse: {e}")))?;
    if source.is_latlong() {
        return Err(fail("a geographic CRS, not a projected one".into()));
    }
    let wgs84 = Proj::from_proj_string("+proj=longlat +datum=WGS84 +no_defs")
        .map_err(|e| fail(e.to_string()))?;
    let to_ecef = |x: f64, y: f64| -> Result<DVec3, PlacementError> {
        let mut p = (x, y, 0.0);
        proj4rs::transform::transform(&source, &wgs84, &mut p)
            .map_err(|e| fail(format!("({x}, {y}) does not project: {e}")))?;
        let (lon, lat) = (p.0.to_degrees(), p.1.to_degrees());
        if !(lon.is_finite() && lat.is_finite()) {
            return Err(fail(format!("({x}, {y}) projects to no position")));
        }
        Ok(geodetic_to_ecef(lon, lat, origin[2]))
    };
    // One metre along each grid axis, measured over ±50 m (central differences).
    let step = 50.0;
    let o = to_ecef(origin[0], origin[1])?;
    let x_axis = (to_ecef(origin[0] + step, origin[1])? - to_ecef(origin[0] - step, origin[1])?)
        / (2.0 * step);
    let y_axis = (to_ecef(origin[0], origin[1] + step)? - to_ecef(origin[0], origin[1] - step)?)
        / (2.0 * step);
    let up = x_axis.cross(y_axis).normalize();
    Ok(DMat4::from_cols(
        x_axis.extend(0.0),
        y_axis.extend(0.0),
        up.extend(0.0),
        DVec4::new(o.x, o.y, o.z, 1.0),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::ecef_to_geodetic;

    #[test]
    fn a_geographic_frame_is_placed_exactly() {
        let frame = Frame::wgs84(-0.17, 51.49);
        let m = root_transform(&frame, None).unwrap();
        // 100 m east of the origin, in the local frame, is on the same parallel.
        let p = m.transform_point3(DVec3::new(100.0, 0.0, 0.0));
        let (lon, lat, h) = ecef_to_geodetic(p);
        assert!((lat - 51.49).abs() < 1e-5, "{lat}");
        assert!(
            lon > -0.17 && (lon + 0.17 - 100.0 / 69_400.0).abs() < 1e-4,
            "{lon}"
        );
        assert!(h.abs() < 1e-2, "{h}");
    }

    #[test]
    fn a_local_frame_needs_a_place() {
        assert_eq!(
            root_transform(&Frame::local(), None),
            Err(PlacementError::NotPlaced)
        );
        assert!(matches!(
            root_transform(&Frame::local(), Some((200.0, 0.0))),
            Err(PlacementError::BadPlace { .. })
        ));
        let m = root_transform(&Frame::local(), Some((4.3, 52.08))).unwrap();
        let (lon, lat, _) = ecef_to_geodetic(m.transform_point3(DVec3::ZERO));
        assert!((lon - 4.3).abs() < 1e-9 && (lat - 52.08).abs() < 1e-9);
    }

    #[test]
    fn rd_new_is_placed_in_the_hague_with_its_grid_convergence() {
        // The Hague in RD New (EPSG:28992, as CityJSON's EPSG:7415 with NAP heights).
        for name in ["EPSG:7415", "https://www.opengis.net/def/crs/EPSG/0/28992"] {
            let frame = Frame::projected(name, [81_000.0, 455_000.0, 0.0]);
            let m = root_transform(&frame, None).unwrap();
            let (lon, lat, _) = ecef_to_geodetic(m.transform_point3(DVec3::ZERO));
            assert!((lon - 4.3077).abs() < 1e-3 && (lat - 52.0783).abs() < 1e-3);
            // Grid north is turned from true north: west of RD's central meridian (5.39° E) by
            // about (5.39 − 4.31)° × sin 52.08° ≈ 0.85°.
            let north = enu_to_ecef(lon, lat, 0.0).col(1).truncate();
            let grid_north = m.col(1).truncate().normalize();
            let angle = north.angle_between(grid_north).to_degrees();
            assert!((0.7..1.0).contains(&angle), "convergence {angle}°");
            // Metres stay metres (RD's scale factor is within 1e-4 of 1 here).
            assert!((m.col(0).truncate().length() - 1.0).abs() < 5e-4);
        }
    }

    #[test]
    fn unknown_crs_is_a_clear_error() {
        let frame = Frame::projected("my-own-grid", [0.0; 3]);
        let err = root_transform(&frame, None).unwrap_err().to_string();
        assert!(err.contains("my-own-grid") && err.contains("EPSG"), "{err}");
        assert_eq!(epsg_code("urn:ogc:def:crs:EPSG::28992"), Some(28992));
        assert_eq!(epsg_code("EPSG:4326"), Some(4326));
        assert_eq!(epsg_code("CRS84"), None);
    }
}
