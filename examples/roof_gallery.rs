//! A glb of every roof shape on hand-made footprints (a rectangle, an L, a block with a
//! narrower wing and a bay, a T, a U and a courtyard house), one row per shape, on flat ground:
//! to look at the roofs with a glTF viewer or `render_glb.mjs`.
//!
//! Usage: roof_gallery OUT.glb [SHAPE,SHAPE…]   (`roof:shape` values; all shapes by default)

use std::collections::BTreeMap;

use terrastitch::features::buildings::{appearance, RoofShape, RoofSpec};
use terrastitch::features::{BuildingShape, FeatureClass, FeatureInfo};
use terrastitch::geometry::{Point, Polygon};
use terrastitch::mesh::buildings::{extrude, solid};

use terrastitch::osm::Tags;
use terrastitch::output::glb::{self, TileDescription};
use terrastitch::TileId;

/// Footprints in metres: outer ring, then holes.
fn footprints() -> Vec<(&'static str, Vec<Vec<Point>>)> {
    let rectangle = vec![vec![[0.0, 0.0], [14.0, 0.0], [14.0, 9.0], [0.0, 9.0]]];
    let l = vec![vec![
        [0.0, 0.0],
        [16.0, 0.0],
        [16.0, 7.0],
        [7.0, 7.0],
        [7.0, 16.0],
        [0.0, 16.0],
    ]];
    // A main block with a narrower wing and a small bay on its long side.
    let extended = vec![vec![
        [0.0, 0.0],
        [18.0, 0.0],
        [18.0, 10.0],
        [11.0, 10.0],
        [11.0, 12.0],
        [7.0, 12.0],
        [7.0, 10.0],
        [6.0, 10.0],
        [6.0, 18.0],
        [0.0, 18.0],
    ]];
    let t = vec![vec![
        [0.0, 0.0],
        [18.0, 0.0],
        [18.0, 7.0],
        [12.0, 7.0],
        [12.0, 17.0],
        [6.0, 17.0],
        [6.0, 7.0],
        [0.0, 7.0],
    ]];
    let u = vec![vec![
        [0.0, 0.0],
        [18.0, 0.0],
        [18.0, 16.0],
        [12.0, 16.0],
        [12.0, 7.0],
        [6.0, 7.0],
        [6.0, 16.0],
        [0.0, 16.0],
    ]];
    let courtyard = vec![
        vec![[0.0, 0.0], [18.0, 0.0], [18.0, 16.0], [0.0, 16.0]],
        vec![[6.0, 5.0], [6.0, 11.0], [12.0, 11.0], [12.0, 5.0]],
    ];
    vec![
        ("rectangle", rectangle),
        ("L", l),
        ("extended", extended),
        ("T", t),
        ("U", u),
        ("courtyard", courtyard),
    ]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::args()
        .nth(1)
        .ok_or("usage: roof_gallery OUT.glb [SHAPE,SHAPE…]")?;
    let shapes: Vec<RoofShape> = match std::env::args().nth(2) {
        None => RoofShape::ALL.to_vec(),
        Some(list) => list
            .split(',')
            .map(|v| RoofShape::from_tag(v).ok_or(format!("unknown roof shape {v}")))
            .collect::<Result<_, _>>()?,
    };
    let tile = TileId {
        z: 14,
        x: 8529,
        y: 5973,
    };
    let frame = tile.frame();
    let mut features = vec![FeatureInfo {
        inferred: Default::default(),
        element: None,
        class: FeatureClass::Terrain,
        tags: Tags::default(),
    }];
    let mut parts = BTreeMap::new();
    let spacing = 30.0;
    for (row, shape) in shapes.iter().enumerate() {
        for (column, (name, rings)) in footprints().into_iter().enumerate() {
            let offset = [20.0 + spacing * column as f64, 20.0 + spacing * row as f64];
            let to_uv = |p: &Point| {
                [
                    f64::from(tile.x) + (p[0] + offset[0]) / frame.size_m,
                    f64::from(tile.y) + (p[1] + offset[1]) / frame.size_m,
                ]
            };
            let footprint = Polygon {
                outer: rings[0].iter().map(to_uv).collect(),
                holes: rings[1..]
                    .iter()
                    .map(|r| r.iter().map(to_uv).collect())
                    .collect(),
            };
            let tags = Tags::from_pairs([
                ("building", "house".to_string()),
                ("roof:shape", format!("{shape:?}")),
                ("name", format!("{shape:?} on {name}")),
            ]);
            features.push(FeatureInfo {
                inferred: Default::default(),
                element: None,
                class: FeatureClass::Building,
                tags: tags.clone(),
            });
            let building = BuildingShape {
                feature: (features.len() - 1) as u32,
                footprint,
                height_m: 9.0,
                height_tagged: true,
                basement_m: 0.0,
                roof: RoofSpec {
                    shape: *shape,
                    height_m: Some(4.0),
                    pitch: 0.6,
                    direction_deg: None,
                    across: false,
                    over_levels: false,
                },
                min_height_m: 0.0,
                drawn: true,
                base: None,
                appearance: appearance(&tags),
                // Blank walls: the roofs are what the gallery shows.
                facade: Default::default(),
                passages: Vec::new(),
            };
            let shell = solid(&building, frame.size_m, 0.0, 0.0);
            extrude(&building, &shell, &frame, &mut parts);
        }
    }
    let description = TileDescription {
        tile,
        bounds: tile.bounds(),
        size_m: frame.size_m,
        generator: "roof_gallery".to_string(),
        vertical_datum: Default::default(),
    };
    let bytes = glb::write(
        &description,
        &parts,
        &BTreeMap::new(),
        &features,
        terrastitch::format::Variant::default(),
    );
    std::fs::write(&out, bytes)?;
    println!(
        "{out}: {} shapes × {} footprints",
        shapes.len(),
        footprints().len()
    );
    Ok(())
}
