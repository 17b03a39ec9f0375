//! Positions on the WGS 84 ellipsoid: geodetic longitude, latitude and height to Earth-centred,
//! Earth-fixed (ECEF) coordinates, the east-north-up axes at a place, and the ellipsoid-scaled
//! frame of quantized-mesh's horizon occlusion point. One set of constants for every writer.

/// WGS 84 semi-major (equatorial) radius, metres.
pub const RADIUS_EQUATOR: f64 = 6_378_137.0;
/// WGS 84 flattening.
pub const FLATTENING: f64 = 1.0 / 298.257_223_563;
/// WGS 84 semi-minor (polar) radius, metres.
pub const RADIUS_POLE: f64 = RADIUS_EQUATOR * (1.0 - FLATTENING);
/// The ellipsoid's radii along ECEF x, y and z.
pub const RADII: [f64; 3] = [RADIUS_EQUATOR, RADIUS_EQUATOR, RADIUS_POLE];

pub type Vector = [f64; 3];

/// Earth-centred, Earth-fixed coordinates of a point given in degrees and metres.
pub fn ecef(lon_deg: f64, lat_deg: f64, height_m: f64) -> Vector {
    let e2 = FLATTENING * (2.0 - FLATTENING);
    let (lon, lat) = (lon_deg.to_radians(), lat_deg.to_radians());
    let n = RADIUS_EQUATOR / (1.0 - e2 * lat.sin().powi(2)).sqrt();
    [
        (n + height_m) * lat.cos() * lon.cos(),
        (n + height_m) * lat.cos() * lon.sin(),
        (n * (1.0 - e2) + height_m) * lat.sin(),
    ]
}

/// The unit east, north and up vectors (Earth-fixed) at a longitude and latitude.
pub fn east_north_up(lon_deg: f64, lat_deg: f64) -> [Vector; 3] {
    let (lon, lat) = (lon_deg.to_radians(), lat_deg.to_radians());
    [
        [-lon.sin(), lon.cos(), 0.0],
        [-lat.sin() * lon.cos(), -lat.sin() * lon.sin(), lat.cos()],
        [lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin()],
    ]
}

/// A vector given in (east, north, up) at a place, in ECEF.
pub fn enu_to_ecef(v: Vector, lon_deg: f64, lat_deg: f64) -> Vector {
    let [east, north, up] = east_north_up(lon_deg, lat_deg);
    [0, 1, 2].map(|i| v[0] * east[i] + v[1] * north[i] + v[2] * up[i])
}

/// ECEF divided by the ellipsoid's radii: the ellipsoid becomes the unit sphere.
pub fn scaled(p: Vector) -> Vector {
    [0, 1, 2].map(|i| p[i] / RADII[i])
}
