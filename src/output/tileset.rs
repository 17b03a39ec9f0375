//! 3D Tiles 1.1 tilesets over the served tiles, for CesiumJS and 3DTilesRendererJS.
//!
//! Web Mercator rows do not split at latitude midpoints, so 3D Tiles implicit tiling cannot
//! describe them: the hierarchy is explicit. Tileset files stand at every second zoom below the
//! content zoom (12, 10, 8, … for content at 14); each lists the sixteen tiles two zooms down
//! that meet the data's coverage, as external tilesets, and the last level lists the content
//! tiles themselves. The root tileset lists the coarsest level at which the coverage takes
//! [`ROOT_CHILDREN`] tiles or fewer. Parents hold no content of their own (`REPLACE`
//! refinement over empty parents): the content appears when the camera is near enough for the
//! parent's geometric error to matter.
//!
//! Every bounding volume is a region (radians, heights in metres): the SRTM heights under the
//! tile widened by [`BELOW_GROUND_M`] and [`ABOVE_GROUND_M`] for tunnels, water and buildings. A
//! content tile carries the transform of its east-north-up frame (see [`super::enu`]); a region
//! is not transformed by it.

use serde_json::{json, Value};

use super::enu::EastNorthUp;
use crate::tile::{LonLatBounds, TileId, TileRange};

/// Zooms between one tileset file and the next.
pub const LEVEL_STEP: u8 = 2;
/// The root lists at most this many tiles (unless even the coarsest level takes more).
pub const ROOT_CHILDREN: u64 = 64;
/// Depth below the lowest terrain a tile's region reaches (tunnels, harbour floors).
pub const BELOW_GROUND_M: f64 = 60.0;
/// Height above the highest terrain a tile's region reaches (buildings, bridges, masts).
pub const ABOVE_GROUND_M: f64 = 350.0;

/// What a tileset is built from: the zoom of the content and the boxes the data covers.
#[derive(Debug, Clone)]
pub struct Plan {
    pub content_zoom: u8,
    pub coverage: Vec<LonLatBounds>,
    /// Appended to every URI (`?compress=meshopt`), empty for none.
    pub query: String,
}

/// Lowest and highest ground under a tile, metres; `None` where no elevation is known.
pub type Heights<'a> = &'a dyn Fn(TileId) -> Option<(f64, f64)>;

/// Used where the SRTM files do not tell (a tile whose files are fetched when first asked
/// for).
const UNKNOWN_HEIGHTS: (f64, f64) = (-100.0, 4000.0);

impl Plan {
    /// The zooms that have tileset files, finest first.
    fn levels(&self) -> impl Iterator<Item = u8> + '_ {
        (1..)
            .map(|k| k * LEVEL_STEP)
            .take_while(|&d| d <= self.content_zoom)
            .map(|d| self.content_zoom - d)
    }

    /// The zoom the root lists.
    pub fn top_zoom(&self) -> u8 {
        let mut top = self.content_zoom;
        for z in self.levels() {
            top = z;
            if self.covered_at(z).len() as u64 <= ROOT_CHILDREN {
                break;
            }
        }
        top
    }

    /// Whether `tile` has a tileset file: at a level, at or below the root's zoom, meeting
    /// the coverage.
    pub fn has_tileset(&self, tile: TileId) -> bool {
        self.levels().any(|z| z == tile.z) && tile.z >= self.top_zoom() && self.meets_coverage(tile)
    }

    fn meets_coverage(&self, tile: TileId) -> bool {
        let bounds = tile.bounds();
        self.coverage.iter().any(|c| c.intersects(&bounds))
    }

    /// The tiles at zoom `z` that meet the coverage, row by row.
    fn covered_at(&self, z: u8) -> Vec<TileId> {
        let mut tiles: Vec<TileId> = self
            .coverage
            .iter()
            .flat_map(|c| TileRange::covering(z, c).tiles().collect::<Vec<_>>())
            .filter(|&t| self.meets_coverage(t))
            .collect();
        tiles.sort_by_key(|t| (t.y, t.x));
        tiles.dedup();
        tiles
    }

    /// The tiles `LEVEL_STEP` zooms below `tile` that meet the coverage.
    fn children(&self, tile: TileId) -> Vec<TileId> {
        let factor: u32 = 1 << LEVEL_STEP;
        let z = tile.z + LEVEL_STEP;
        (0..factor)
            .flat_map(|dy| (0..factor).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| TileId {
                z,
                x: tile.x * factor + dx,
                y: tile.y * factor + dy,
            })
            .filter(|&t| self.meets_coverage(t))
            .collect()
    }

    /// Geometric error of a tile without content whose children are at zoom `z` (near
    /// `tile`): a twelfth of a child's ground size, so that (at CesiumJS's default of 16 pixels)
    /// content tiles open from about 8 km away on a 1,000-pixel-high view.
    fn geometric_error(&self, z: u8, tile: TileId) -> f64 {
        let latitude = (tile.bounds().north + tile.bounds().south) / 2.0;
        let ground = TileId { z, x: 0, y: 0 }.size_m() * latitude.to_radians().cos();
        ground / 12.0
    }

    fn region(tile: TileId, heights: Heights<'_>) -> Value {
        let b = tile.bounds();
        let (low, high) = heights(tile).unwrap_or(UNKNOWN_HEIGHTS);
        json!({
            "region": [
                b.west.to_radians(),
                b.south.to_radians(),
                b.east.to_radians(),
                b.north.to_radians(),
                low - BELOW_GROUND_M,
                high + ABOVE_GROUND_M
            ]
        })
    }

    /// A tile entry: content tiles with their content and transform, others pointing at their
    /// own tileset file (`from_level` is the zoom of the file that lists it).
    fn entry(&self, tile: TileId, from_level: Option<u8>, heights: Heights<'_>) -> Value {
        let up = match from_level {
            // From `3dtiles/{z}/{x}/{y}.json` back to `3dtiles/`.
            Some(_) => "../../",
            // From `/tileset.json`.
            None => "3dtiles/",
        };
        if tile.z == self.content_zoom {
            json!({
                "boundingVolume": Self::region(tile, heights),
                "geometricError": 0.0,
                "refine": "REPLACE",
                "transform": EastNorthUp::new(tile).transform(),
                "content": {
                    "uri": format!("{up}{}/{}/{}.glb{}", tile.z, tile.x, tile.y, self.query)
                }
            })
        } else {
            json!({
                "boundingVolume": Self::region(tile, heights),
                "geometricError": self.geometric_error(tile.z + LEVEL_STEP, tile),
                "refine": "REPLACE",
                "content": {
                    "uri": format!("{up}{}/{}/{}.json{}", tile.z, tile.x, tile.y, self.query)
                }
            })
        }
    }

    fn asset() -> Value {
        json!({
            "version": "1.1",
            "generator": concat!("terrastitch ", env!("CARGO_PKG_VERSION")),
        })
    }

    /// `/tileset.json`: a root over the coverage whose children are the top level's tiles.
    pub fn root(&self, heights: Heights<'_>) -> Value {
        let top = self.top_zoom();
        let tiles = self.covered_at(top);
        let children: Vec<Value> = tiles
            .iter()
            .map(|&t| self.entry(t, None, heights))
            .collect();
        let mut region = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let (mut low, mut high) = (f64::INFINITY, f64::NEG_INFINITY);
        for child in &children {
            let r = &child["boundingVolume"]["region"];
            let at = |i: usize| r[i].as_f64().unwrap_or(0.0);
            region = [
                region[0].min(at(0)),
                region[1].min(at(1)),
                region[2].max(at(2)),
                region[3].max(at(3)),
            ];
            low = low.min(at(4));
            high = high.max(at(5));
        }
        if children.is_empty() {
            region = [0.0; 4];
            (low, high) = (0.0, 0.0);
        }
        let error = tiles
            .first()
            .map_or(0.0, |&t| 4.0 * self.geometric_error(top + LEVEL_STEP, t));
        json!({
            "asset": Self::asset(),
            "geometricError": error,
            "root": {
                "boundingVolume": {
                    "region": [region[0], region[1], region[2], region[3], low, high]
                },
                "geometricError": error,
                "refine": "REPLACE",
                "children": children
            }
        })
    }

    /// `/3dtiles/{z}/{x}/{y}.json`: the tile and the tiles `LEVEL_STEP` zooms below it.
    pub fn subtree(&self, tile: TileId, heights: Heights<'_>) -> Value {
        let error = self.geometric_error(tile.z + LEVEL_STEP, tile);
        let children: Vec<Value> = self
            .children(tile)
            .into_iter()
            .map(|t| self.entry(t, Some(tile.z), heights))
            .collect();
        json!({
            "asset": Self::asset(),
            "geometricError": error,
            "root": {
                "boundingVolume": Self::region(tile, heights),
                "geometricError": error,
                "refine": "REPLACE",
                "children": children
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn monaco() -> Plan {
        Plan {
            content_zoom: 14,
            coverage: vec!["7.40,43.72,7.44,43.75".parse().unwrap()],
            query: String::new(),
        }
    }

    fn flat(_: TileId) -> Option<(f64, f64)> {
        Some((0.0, 160.0))
    }

    #[test]
    fn the_root_lists_the_parents_of_the_content_and_they_list_the_content() {
        let plan = monaco();
        assert_eq!(plan.top_zoom(), 12);
        let root = plan.root(&flat);
        assert_eq!(root["asset"]["version"], "1.1");
        let children = root["root"]["children"].as_array().unwrap();
        assert!(!children.is_empty() && children.len() <= 4);
        let mut content = Vec::new();
        for child in children {
            let uri = child["content"]["uri"].as_str().unwrap();
            assert!(
                uri.starts_with("3dtiles/12/") && uri.ends_with(".json"),
                "{uri}"
            );
            let parts: Vec<u32> = uri
                .trim_start_matches("3dtiles/")
                .trim_end_matches(".json")
                .split('/')
                .map(|p| p.parse().unwrap())
                .collect();
            let parent = TileId {
                z: parts[0] as u8,
                x: parts[1],
                y: parts[2],
            };
            assert!(plan.has_tileset(parent));
            let subtree = plan.subtree(parent, &flat);
            for leaf in subtree["root"]["children"].as_array().unwrap() {
                assert_eq!(leaf["geometricError"], 0.0);
                assert_eq!(leaf["transform"].as_array().unwrap().len(), 16);
                let uri = leaf["content"]["uri"].as_str().unwrap().to_string();
                assert!(
                    uri.starts_with("../../14/") && uri.ends_with(".glb"),
                    "{uri}"
                );
                content.push(uri);
            }
        }
        // Exactly the zoom-14 tiles the box touches, each once.
        let expected = TileRange::covering(14, &plan.coverage[0]);
        assert_eq!(content.len() as u64, expected.len());
        content.sort();
        content.dedup();
        assert_eq!(content.len() as u64, expected.len());
    }

    #[test]
    fn regions_hold_the_ground_and_what_stands_on_it_and_nest() {
        let plan = monaco();
        let parent = TileId {
            z: 12,
            x: 2132,
            y: 1493,
        };
        let subtree = plan.subtree(parent, &flat);
        let outer = subtree["root"]["boundingVolume"]["region"]
            .as_array()
            .unwrap();
        for leaf in subtree["root"]["children"].as_array().unwrap() {
            let r = leaf["boundingVolume"]["region"].as_array().unwrap();
            let v = |a: &Vec<Value>, i: usize| a[i].as_f64().unwrap();
            assert!(v(r, 0) >= v(outer, 0) - 1e-12 && v(r, 2) <= v(outer, 2) + 1e-12);
            assert!(v(r, 1) >= v(outer, 1) - 1e-12 && v(r, 3) <= v(outer, 3) + 1e-12);
            assert_eq!(v(r, 4), -BELOW_GROUND_M);
            assert_eq!(v(r, 5), 160.0 + ABOVE_GROUND_M);
        }
        // Parents open before their children would: a coarser level has a larger error.
        let coarse = plan.geometric_error(12, parent);
        let fine = plan.geometric_error(14, parent);
        assert!(coarse > 3.0 * fine && fine > 10.0, "{coarse} {fine}");
    }

    #[test]
    fn a_large_coverage_starts_further_up() {
        let plan = Plan {
            content_zoom: 14,
            coverage: vec!["5.0,43.0,8.0,45.0".parse().unwrap()],
            query: "?compress=meshopt".to_string(),
        };
        let top = plan.top_zoom();
        assert!(top < 12 && (14 - top) % LEVEL_STEP == 0, "{top}");
        assert!(plan.covered_at(top).len() as u64 <= ROOT_CHILDREN);
        let root = plan.root(&flat);
        let uri = root["root"]["children"][0]["content"]["uri"]
            .as_str()
            .unwrap();
        assert!(uri.ends_with(".json?compress=meshopt"), "{uri}");
        // A level that is not a tileset level, or a tile outside the data, has no file.
        assert!(!plan.has_tileset(TileId { z: 13, x: 0, y: 0 }));
        assert!(!plan.has_tileset(TileId { z: top, x: 0, y: 0 }));
    }
}
