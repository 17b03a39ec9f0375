//! `render.vertical_datum = "egm96"`: east-north-up content and quantized-mesh terrain in
//! heights above the WGS 84 ellipsoid (SRTM's plus the EGM96 geoid's undulation), so tiles sit
//! on a terrain in ellipsoid heights; the flat frame keeps SRTM's heights.

use crate::common;

use common::{decode, sample_osm, sample_srtm};
use terrastitch::config::Config;
use terrastitch::format::{Extensions, Format, Frame, TileKey, Variant};
use terrastitch::geoid::{undulation, VerticalDatum};
use terrastitch::provider::{Deadline, Inputs, Renderer, TileProvider};
use terrastitch::TileId;

const TILE: TileId = TileId {
    z: 14,
    x: 8529,
    y: 5974,
};

fn renderer(datum: VerticalDatum) -> Renderer {
    let config = Config::default();
    let inputs = Inputs::open(&[sample_osm()], &sample_srtm(), config.server.zoom).unwrap();
    let mut settings = config.render;
    settings.vertical_datum = datum;
    Renderer::new(inputs, settings, config.server.zoom)
}

fn make(renderer: &Renderer, format: Format) -> Vec<u8> {
    renderer
        .make(TileKey { tile: TILE, format }, Deadline::none())
        .unwrap()
        .bytes
}

/// The quantized-mesh header's height range.
fn height_range(terrain: &[u8]) -> (f32, f32) {
    let at = |offset: usize| f32::from_le_bytes(terrain[offset..offset + 4].try_into().unwrap());
    (at(24), at(28))
}

#[test]
fn with_egm96_content_and_terrain_stand_the_geoid_higher() {
    let srtm = renderer(VerticalDatum::Srtm);
    let egm96 = renderer(VerticalDatum::Egm96);
    let bounds = TILE.bounds();
    let (lon, lat) = (
        (bounds.west + bounds.east) / 2.0,
        (bounds.south + bounds.north) / 2.0,
    );
    let n = undulation(lon, lat);
    assert!((47.0..50.0).contains(&n), "EGM96 at Monaco: {n}");

    // Every ground vertex of the east-north-up content moves by the undulation at its place,
    // along the ellipsoid's normal there: a point of SRTM height h lands at h + N.
    let enu = Format::Glb(Variant {
        frame: Frame::EastNorthUp,
        meshopt: false,
    });
    let (plain, raised) = (decode(&make(&srtm, enu)), decode(&make(&egm96, enu)));
    let mut moved = 0;
    for (primitive, other) in plain
        .primitives("terrain")
        .iter()
        .zip(raised.primitives("terrain"))
    {
        assert_eq!(primitive.positions.len(), other.positions.len());
        for (a, b) in primitive.positions.iter().zip(&other.positions) {
            let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]].map(f64::from);
            let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            assert!(
                (length - n).abs() < 1.0,
                "moved {length} m, the geoid is {n} m"
            );
            // Upwards: mostly along the frame's up (y).
            assert!(d[1] > 0.99 * length, "{d:?}");
            moved += 1;
        }
    }
    assert!(moved > 1000, "{moved} ground vertices");

    // The terrain tile's heights, and the flat frame's content, as the datum says.
    let terrain = Format::Terrain(Extensions::default());
    let (low, high) = height_range(&make(&srtm, terrain));
    let (low_raised, high_raised) = height_range(&make(&egm96, terrain));
    assert!(
        (f64::from(low_raised - low) - n).abs() < 1.0,
        "{low} → {low_raised}"
    );
    assert!(
        (f64::from(high_raised - high) - n).abs() < 1.0,
        "{high} → {high_raised}"
    );
    assert_eq!(make(&srtm, Format::GLB), make(&egm96, Format::GLB));
}

#[test]
fn the_default_datum_leaves_the_pipeline_fingerprint_as_it_was() {
    let settings = Config::default().render;
    assert_eq!(settings.vertical_datum, VerticalDatum::Srtm);
    // The fingerprint of the default settings, as recorded: a change of a default or of how
    // the settings are written changes it, and with it the provenance of every stored tile.
    assert_eq!(settings.fingerprint(), "15b15e4eaf7f");
    let mut egm96 = settings.clone();
    egm96.vertical_datum = VerticalDatum::Egm96;
    assert_ne!(settings.fingerprint(), egm96.fingerprint());
}
