//! Tile ids, their bounds and the tile's local frame.
//!
//! Tiles are numbered as slippy-map (XYZ) tiles of Web Mercator (EPSG:3857): `x` grows eastwards
//! from 180° W, `y` southwards from 85.0511° N (notes 004 §1).
//!
//! Positions are first expressed in *global tile units*: `u = (lon + 180) / 360 · 2^z` and
//! `v = (1 − ln(tan φ + sec φ) / π) / 2 · 2^z`, so tile `(x, y)` spans `u ∈ [x, x+1]`,
//! `v ∈ [y, y+1]`. The tile's local frame (glTF, Y up) is
//!
//! * `x_local = (u − x) · S` metres east of the tile's north-west corner,
//! * `z_local = (v − y) · S` metres south of it,
//! * `y_local = elevation · k(φ)`, where `k(φ) = 1 / cos φ` is the Mercator scale factor at the
//!   vertex's own latitude, so shapes keep their proportions in the Mercator plane,
//!
//! with `S = 40 075 016.686 / 2^z` the tile size in Mercator metres. Two neighbouring tiles placed
//! by translation by `S` line up exactly: a point on a shared edge has `u − x` equal to exactly 0 in
//! one tile and exactly 1 in the other, and the same other coordinate in both.

use std::fmt;
use std::str::FromStr;

/// Circumference of the Web Mercator sphere at the equator, in metres (2π · 6 378 137).
pub const EARTH_CIRCUMFERENCE_M: f64 = 40_075_016.685_578_49;

/// Latitude limit of Web Mercator: the square world ends here.
pub const MAX_LATITUDE_DEG: f64 = 85.051_128_779_806_59;

/// Highest zoom level this crate accepts; 2^30 tiles per axis still fits in a `u32`.
pub const MAX_ZOOM: u8 = 30;

/// A slippy-map tile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TileId {
    pub z: u8,
    pub x: u32,
    pub y: u32,
}

/// Why a tile id was rejected.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum TileIdError {
    #[error("zoom {0} is above the maximum zoom {MAX_ZOOM}")]
    ZoomTooHigh(u64),
    #[error("x = {x} is outside 0..{limit} at zoom {z}")]
    XOutOfRange { z: u8, x: u64, limit: u64 },
    #[error("y = {y} is outside 0..{limit} at zoom {z}")]
    YOutOfRange { z: u8, y: u64, limit: u64 },
    #[error("'{0}' is not a tile id of the form Z/X/Y")]
    Syntax(String),
    #[error("{name} = '{text}' is not a non-negative integer")]
    NotANumber { name: &'static str, text: String },
    #[error("{name} = '{text}' is not written as tiles are named: write {name} = {canonical}")]
    NotCanonical {
        name: &'static str,
        text: String,
        canonical: u64,
    },
}

impl TileId {
    /// Checks that `x` and `y` lie inside `0..2^z`.
    pub fn new(z: u32, x: u64, y: u64) -> Result<Self, TileIdError> {
        if z > u32::from(MAX_ZOOM) {
            return Err(TileIdError::ZoomTooHigh(u64::from(z)));
        }
        let z = z as u8;
        let limit = 1u64 << z;
        if x >= limit {
            return Err(TileIdError::XOutOfRange { z, x, limit });
        }
        if y >= limit {
            return Err(TileIdError::YOutOfRange { z, y, limit });
        }
        Ok(TileId {
            z,
            x: x as u32,
            y: y as u32,
        })
    }

    /// Number of tiles along one axis at this zoom.
    pub fn tiles_per_axis(self) -> f64 {
        f64::from(1u32 << self.z.min(31))
    }

    /// Edge length of the tile in Web Mercator metres.
    pub fn size_m(self) -> f64 {
        EARTH_CIRCUMFERENCE_M / self.tiles_per_axis()
    }

    /// The tile's bounds in degrees.
    pub fn bounds(self) -> LonLatBounds {
        let n = self.tiles_per_axis();
        LonLatBounds {
            west: u_to_lon(f64::from(self.x), n),
            east: u_to_lon(f64::from(self.x) + 1.0, n),
            north: v_to_lat(f64::from(self.y), n),
            south: v_to_lat(f64::from(self.y) + 1.0, n),
        }
    }

    /// The tile that contains a point, at zoom `z`.
    pub fn containing(z: u8, lon: f64, lat: f64) -> Option<TileId> {
        let n = f64::from(1u32 << z.min(31));
        let (u, v) = lon_lat_to_uv(lon, lat, n);
        if !(0.0..n).contains(&u) || !(0.0..n).contains(&v) {
            return None;
        }
        TileId::new(u32::from(z), u.floor() as u64, v.floor() as u64).ok()
    }

    /// The local frame of this tile.
    pub fn frame(self) -> TileFrame {
        TileFrame {
            tile: self,
            size_m: self.size_m(),
            tiles_per_axis: self.tiles_per_axis(),
        }
    }
}

impl TileId {
    /// Reads a tile from the three numbers of a path (`z`, `x`, `y` as written), checked as
    /// [`TileId::new`] checks them: the one parser of tile paths, for URLs and the command line.
    pub fn from_parts(z: &str, x: &str, y: &str) -> Result<TileId, TileIdError> {
        // Digits only, without leading zeros: one tile, one name (a cache holds no copies).
        let number = |name: &'static str, text: &str| {
            let value = text.parse::<u64>().map_err(|_| TileIdError::NotANumber {
                name,
                text: text.to_string(),
            })?;
            match value.to_string() == text {
                true => Ok(value),
                false => Err(TileIdError::NotCanonical {
                    name,
                    text: text.to_string(),
                    canonical: value,
                }),
            }
        };
        let zoom = number("z", z)?;
        let zoom = u32::try_from(zoom).map_err(|_| TileIdError::ZoomTooHigh(zoom))?;
        TileId::new(zoom, number("x", x)?, number("y", y)?)
    }
}

impl fmt::Display for TileId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}/{}", self.z, self.x, self.y)
    }
}

impl FromStr for TileId {
    type Err = TileIdError;

    /// Parses `Z/X/Y`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts: Vec<&str> = s.trim().split('/').collect();
        let [z, x, y] = parts.as_slice() else {
            return Err(TileIdError::Syntax(s.to_string()));
        };
        TileId::from_parts(z, x, y)
    }
}

/// A rectangle in longitude and latitude (degrees).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LonLatBounds {
    pub west: f64,
    pub south: f64,
    pub east: f64,
    pub north: f64,
}

impl LonLatBounds {
    pub fn intersects(&self, other: &LonLatBounds) -> bool {
        self.west < other.east
            && other.west < self.east
            && self.south < other.north
            && other.south < self.north
    }

    /// Grows the rectangle by `margin_deg` on every side.
    pub fn expanded(&self, margin_deg: f64) -> LonLatBounds {
        LonLatBounds {
            west: self.west - margin_deg,
            south: self.south - margin_deg,
            east: self.east + margin_deg,
            north: self.north + margin_deg,
        }
    }
}

impl FromStr for LonLatBounds {
    type Err = String;

    /// Parses `W,S,E,N` in degrees.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let numbers: Vec<f64> = s
            .split(',')
            .map(|part| part.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("'{s}' is not a box W,S,E,N of four numbers in degrees"))?;
        let [west, south, east, north] = numbers.as_slice() else {
            return Err(format!(
                "'{s}' is not a box W,S,E,N of four numbers in degrees"
            ));
        };
        let bounds = LonLatBounds {
            west: *west,
            south: *south,
            east: *east,
            north: *north,
        };
        if !(-180.0..=180.0).contains(&bounds.west)
            || !(-180.0..=180.0).contains(&bounds.east)
            || !(-90.0..=90.0).contains(&bounds.south)
            || !(-90.0..=90.0).contains(&bounds.north)
        {
            return Err(format!(
                "box {s} lies outside longitudes ±180 and latitudes ±90"
            ));
        }
        if bounds.west >= bounds.east || bounds.south >= bounds.north {
            return Err(format!(
                "box {s} is empty: west must be below east and south below north"
            ));
        }
        Ok(bounds)
    }
}

/// The tiles of one zoom that a box touches: columns `min_x..=max_x`, rows `min_y..=max_y`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TileRange {
    pub z: u8,
    pub min_x: u32,
    pub max_x: u32,
    pub min_y: u32,
    pub max_y: u32,
}

impl TileRange {
    /// The tiles at zoom `z` that overlap `bounds` (clamped to the Web Mercator square).
    pub fn covering(z: u8, bounds: &LonLatBounds) -> TileRange {
        let n = f64::from(1u32 << z.min(MAX_ZOOM));
        let last = (n as u64).saturating_sub(1) as f64;
        let lat = |l: f64| l.clamp(-MAX_LATITUDE_DEG, MAX_LATITUDE_DEG);
        let (u0, v0) = lon_lat_to_uv(bounds.west, lat(bounds.north), n);
        let (u1, v1) = lon_lat_to_uv(bounds.east, lat(bounds.south), n);
        // A box ending on a tile edge (within rounding) does not reach the tile beyond it.
        const EDGE: f64 = 1e-9;
        let first = |t: f64| (t + EDGE).floor().clamp(0.0, last) as u32;
        let end = |t: f64| ((t - EDGE).ceil() - 1.0).clamp(0.0, last) as u32;
        TileRange {
            z,
            min_x: first(u0),
            max_x: end(u1).max(first(u0)),
            min_y: first(v0),
            max_y: end(v1).max(first(v0)),
        }
    }

    pub fn len(&self) -> u64 {
        u64::from(self.max_x - self.min_x + 1) * u64::from(self.max_y - self.min_y + 1)
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    pub fn contains(&self, tile: TileId) -> bool {
        tile.z == self.z
            && (self.min_x..=self.max_x).contains(&tile.x)
            && (self.min_y..=self.max_y).contains(&tile.y)
    }

    /// The tiles row by row, north to south, west to east.
    pub fn tiles(&self) -> impl Iterator<Item = TileId> + '_ {
        let z = self.z;
        (self.min_y..=self.max_y)
            .flat_map(move |y| (self.min_x..=self.max_x).map(move |x| TileId { z, x, y }))
    }
}

/// Longitude and latitude to global tile units at `n` tiles per axis.
pub fn lon_lat_to_uv(lon: f64, lat: f64, n: f64) -> (f64, f64) {
    let u = (lon + 180.0) / 360.0 * n;
    let lat = lat.clamp(-MAX_LATITUDE_DEG, MAX_LATITUDE_DEG).to_radians();
    let v = (1.0 - (lat.tan() + 1.0 / lat.cos()).ln() / std::f64::consts::PI) / 2.0 * n;
    (u, v)
}

/// Global tile units back to longitude (degrees).
pub fn u_to_lon(u: f64, n: f64) -> f64 {
    u / n * 360.0 - 180.0
}

/// Global tile units back to latitude (degrees).
pub fn v_to_lat(v: f64, n: f64) -> f64 {
    let mercator_y = std::f64::consts::PI * (1.0 - 2.0 * v / n);
    mercator_y.sinh().atan().to_degrees()
}

/// Mercator scale factor `1 / cos φ` at a latitude in degrees.
pub fn mercator_scale(lat_deg: f64) -> f64 {
    1.0 / lat_deg.to_radians().cos()
}

/// A tile's local metric frame (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TileFrame {
    pub tile: TileId,
    pub size_m: f64,
    tiles_per_axis: f64,
}

impl TileFrame {
    /// Longitude and latitude to local `(x, z)` metres.
    pub fn to_local(&self, lon: f64, lat: f64) -> (f64, f64) {
        let (u, v) = lon_lat_to_uv(lon, lat, self.tiles_per_axis);
        self.uv_to_local(u, v)
    }

    /// Global tile units to local `(x, z)` metres.
    pub fn uv_to_local(&self, u: f64, v: f64) -> (f64, f64) {
        (
            (u - f64::from(self.tile.x)) * self.size_m,
            (v - f64::from(self.tile.y)) * self.size_m,
        )
    }

    /// True for a local point exactly on the tile's edge: a vertex there is shared with the
    /// neighbour, and its elevation and normal are made from what both tiles know alike.
    pub fn on_edge(&self, [x, z]: [f64; 2]) -> bool {
        let size = self.size_m;
        x == 0.0 || z == 0.0 || x == size || z == size
    }

    /// Local `(x, z)` metres to global tile units.
    pub fn local_to_uv(&self, x: f64, z: f64) -> (f64, f64) {
        (
            f64::from(self.tile.x) + x / self.size_m,
            f64::from(self.tile.y) + z / self.size_m,
        )
    }

    /// Local `(x, z)` metres to longitude and latitude.
    pub fn to_lon_lat(&self, x: f64, z: f64) -> (f64, f64) {
        let (u, v) = self.local_to_uv(x, z);
        (
            u_to_lon(u, self.tiles_per_axis),
            v_to_lat(v, self.tiles_per_axis),
        )
    }

    /// Metres in the local frame per metre on the ground at local `z`.
    pub fn scale_at(&self, z: f64) -> f64 {
        let (_, v) = self.local_to_uv(0.0, z);
        mercator_scale(v_to_lat(v, self.tiles_per_axis))
    }

    /// The local `y` of an elevation in metres at local `z`.
    pub fn elevation_to_y(&self, elevation_m: f64, z: f64) -> f64 {
        elevation_m * self.scale_at(z)
    }
}

/// The levels above the served zoom that glb tiles are made at for far views: the parents of
/// the 3D Tiles hierarchy. The zoom policy the renderer, the provider's offer and the tileset
/// writer share.
pub const OVERVIEW_LEVELS: [u8; 4] = [1, 2, 4, 6];

/// Whether glb tiles are made at `zoom` for far views when the served zoom is `served_zoom`.
pub fn is_overview_zoom(zoom: u8, served_zoom: u8) -> bool {
    served_zoom
        .checked_sub(zoom)
        .is_some_and(|d| OVERVIEW_LEVELS.contains(&d))
}

/// The zooms of far views, finest first.
pub fn overview_zooms(served_zoom: u8) -> Vec<u8> {
    OVERVIEW_LEVELS
        .iter()
        .filter_map(|&d| served_zoom.checked_sub(d))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_paths_are_read_from_their_three_numbers() {
        assert_eq!(
            TileId::from_parts("14", "8529", "5973"),
            Ok(TileId {
                z: 14,
                x: 8529,
                y: 5973
            })
        );
        assert_eq!(
            "14/8529/5973".parse(),
            TileId::from_parts("14", "8529", "5973")
        );
        assert_eq!(
            TileId::from_parts("14", "abc", "1"),
            Err(TileIdError::NotANumber {
                name: "x",
                text: "abc".into()
            })
        );
        assert!(matches!(
            TileId::from_parts("-1", "0", "0"),
            Err(TileIdError::NotANumber { name: "z", .. })
        ));
        assert_eq!(
            TileId::from_parts("99999999999", "0", "0"),
            Err(TileIdError::ZoomTooHigh(99_999_999_999))
        );
        assert!(matches!(
            TileId::from_parts("14", "16384", "0"),
            Err(TileIdError::XOutOfRange { .. })
        ));
    }

    #[test]
    fn a_tile_has_one_name_only() {
        for (x, y) in [("08529", "5973"), ("+8529", "5973"), ("8529", "05973")] {
            let error = TileId::from_parts("14", x, y).unwrap_err();
            assert!(matches!(error, TileIdError::NotCanonical { .. }), "{x}/{y}");
            assert!(error.to_string().contains("write"), "{error}");
        }
        assert!(TileId::from_parts("014", "8529", "5973").is_err());
        assert_eq!(
            TileId::from_parts("0", "0", "0"),
            Ok(TileId { z: 0, x: 0, y: 0 })
        );
    }

    #[test]
    fn a_box_covers_the_tiles_it_touches_and_no_more() {
        let monaco: LonLatBounds = "7.40,43.72,7.44,43.75".parse().unwrap();
        let range = TileRange::covering(14, &monaco);
        for tile in range.tiles() {
            assert!(tile.bounds().intersects(&monaco), "{tile}");
        }
        assert_eq!(range.tiles().count() as u64, range.len());
        // A box that is exactly one tile covers that tile alone.
        let tile = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        };
        let exact = TileRange::covering(14, &tile.bounds());
        assert_eq!(exact.len(), 1);
        assert!(exact.contains(tile));
        for bad in ["1,2,3", "7.44,43.72,7.40,43.75", "a,b,c,d", "0,0,200,1"] {
            assert!(bad.parse::<LonLatBounds>().is_err(), "{bad}");
        }
    }

    #[test]
    fn beausoleil_lies_in_its_published_tile() {
        let tile = TileId::containing(14, 7.4200, 43.7450).unwrap();
        assert_eq!(
            tile,
            TileId {
                z: 14,
                x: 8529,
                y: 5973
            }
        );
    }

    #[test]
    fn bounds_match_the_published_tile_box() {
        let b = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        }
        .bounds();
        assert!((b.south - 43.73935).abs() < 1e-5, "{b:?}");
        assert!((b.north - 43.75523).abs() < 1e-5, "{b:?}");
        assert!((b.west - 7.40479).abs() < 1e-5, "{b:?}");
        assert!((b.east - 7.42676).abs() < 1e-5, "{b:?}");
    }

    #[test]
    fn shared_edge_is_exact_between_neighbours() {
        let west = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        }
        .frame();
        let east = TileId {
            z: 14,
            x: 8530,
            y: 5973,
        }
        .frame();
        let (u, v) = (8530.0, 5973.37);
        let (xw, zw) = west.uv_to_local(u, v);
        let (xe, ze) = east.uv_to_local(u, v);
        assert_eq!(xw, west.size_m);
        assert_eq!(xe, 0.0);
        assert_eq!(zw.to_bits(), ze.to_bits());
    }

    #[test]
    fn round_trip_through_the_local_frame() {
        let frame = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        }
        .frame();
        let (x, z) = frame.to_local(7.415, 43.745);
        let (lon, lat) = frame.to_lon_lat(x, z);
        assert!((lon - 7.415).abs() < 1e-12 && (lat - 43.745).abs() < 1e-12);
        assert!(x > 0.0 && x < frame.size_m && z > 0.0 && z < frame.size_m);
    }

    #[test]
    fn parses_and_rejects_ids() {
        assert_eq!(
            "14/8529/5973".parse(),
            Ok(TileId {
                z: 14,
                x: 8529,
                y: 5973
            })
        );
        assert!(matches!(
            "14/abc/1".parse::<TileId>(),
            Err(TileIdError::NotANumber { name: "x", .. })
        ));
        assert!(matches!(
            "14/1".parse::<TileId>(),
            Err(TileIdError::Syntax(_))
        ));
        assert!(matches!(
            "14/99999/1".parse::<TileId>(),
            Err(TileIdError::XOutOfRange { .. })
        ));
        assert!(matches!(
            "31/0/0".parse::<TileId>(),
            Err(TileIdError::ZoomTooHigh(31))
        ));
    }

    #[test]
    fn scale_factor_grows_with_latitude() {
        assert!((mercator_scale(60.0) - 2.0).abs() < 1e-12);
        assert!((mercator_scale(0.0) - 1.0).abs() < 1e-15);
    }
}
