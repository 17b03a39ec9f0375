//! 3D Tiles 1.1 tilesets over the served tiles, for CesiumJS and 3DTilesRendererJS.
//!
//! Web Mercator rows do not split at latitude midpoints, so 3D Tiles implicit tiling cannot
//! describe them: the hierarchy is explicit. Tileset files stand at every second zoom below the
//! content zoom (12, 10, 8, … for content at 14); each lists the sixteen tiles two zooms down
//! that meet the data's coverage, as external tilesets, and the last level lists the content
//! tiles themselves. The root tileset lists the finest level (from 12 up) at which the coverage
//! takes [`ROOT_CHILDREN`] tiles or fewer. Parents at the zooms of far views (13, 12, 10 and 8
//! under content at 14, see [`is_overview_zoom`]) carry their own generalised content, which their
//! children replace as the camera nears (`REPLACE`); a tileset file at 12 lists the tiles of
//! 13 inline, each with its four children. A tile with content is placed by its east-north-up
//! frame, written relative to its parent's, since a tile's transform applies to its children.
//! Parents at other zooms, and every parent of an archive of one zoom, are empty.
//!
//! Every bounding volume is a region (radians, heights in metres): the SRTM heights under the
//! tile widened by [`BELOW_GROUND_M`] and [`ABOVE_GROUND_M`] for tunnels, water and buildings
//! (for a content tile, the samples inside it; for a parent, the whole SRTM files it overlaps,
//! which hold its children's, and a parent's region is widened to its children's anyway). A
//! tile whose ground is unknown (its SRTM files missing) is left out, unless the server fetches
//! them when asked ([`Plan::list_unknown`]). A content tile carries the transform of its east-north-up frame (see [`super::enu`]); a region
//! is not transformed by it.

use serde_json::{json, Value};

use super::enu::EastNorthUp;
use crate::tile::{is_overview_zoom, LonLatBounds, TileId, TileRange};

/// Zooms between one tileset file and the next.
pub const LEVEL_STEP: u8 = 2;
/// The root lists at most this many tiles (unless even the coarsest level takes more).
pub const ROOT_CHILDREN: u64 = 64;
/// Depth below the lowest terrain a tile's region reaches (tunnels, harbour floors).
pub const BELOW_GROUND_M: f64 = 60.0;
/// Height above the highest terrain a tile's region reaches (buildings, bridges, masts).
pub const ABOVE_GROUND_M: f64 = 350.0;

/// Where a root tileset file is served.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Root {
    /// `/tileset.json`.
    Top,
    /// `/3dtiles/tileset.json`: clients that take a tileset's folder by cutting its URL at the
    /// last slash (3DTilesRendererJS) get `//` from a file at a server's root.
    InFolder,
}

/// What a tileset is built from: the zoom of the content and the boxes the data covers.
#[derive(Debug, Clone)]
pub struct Plan {
    pub content_zoom: u8,
    pub coverage: Vec<LonLatBounds>,
    /// Appended to every URI (`?compress=meshopt`), empty for none.
    pub query: String,
    /// List tiles whose ground is unknown, with a wide height range (SRTM files are fetched
    /// when a tile is asked for, or an archive is served without sources).
    pub list_unknown: bool,
    /// The parents at the zooms of far views carry content of their own
    /// ([`is_overview_zoom`]); without it (an archive of one zoom), parents are empty.
    pub parent_content: bool,
    /// For a directory export: the content files are `{z}/{x}/{y}{suffix}` beside one tileset
    /// document that lists every tile inline. `None`: the served paths, with a tileset file
    /// every [`LEVEL_STEP`] zooms.
    pub files: Option<String>,
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

    /// The zoom the root lists: the finest level whose tiles over the coverage number
    /// [`ROOT_CHILDREN`] or fewer (counted from the boxes' tile ranges, without listing them).
    pub fn top_zoom(&self) -> u8 {
        let mut top = self.content_zoom;
        for z in self.levels() {
            top = z;
            let count: u64 = self
                .coverage
                .iter()
                .map(|c| TileRange::covering(z, c).len())
                .sum();
            if count <= ROOT_CHILDREN {
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
        ground_size(z, tile) / 12.0
    }

    /// Whether `tile` has content: the content zoom, and the parents at the zooms of far views.
    fn has_content(&self, tile: TileId) -> bool {
        tile.z == self.content_zoom
            || (self.parent_content && is_overview_zoom(tile.z, self.content_zoom))
    }

    /// The error of a tile's own content, metres: none at the content zoom; for a parent, what
    /// its generalisation leaves out or moves: areas and blocks narrower than eight
    /// tolerances (a 128th of its ground size) and heights averaged over blocks, bounded by
    /// twice that. Errors shrink from each level of content to the next.
    fn content_error(&self, tile: TileId) -> f64 {
        if tile.z >= self.content_zoom {
            return 0.0;
        }
        ground_size(tile.z, tile) / 64.0
    }

    /// The geometric error of a listed tile.
    fn error_of(&self, tile: TileId) -> f64 {
        if self.has_content(tile) {
            self.content_error(tile)
        } else {
            self.geometric_error(tile.z + LEVEL_STEP, tile)
        }
    }

    /// Where a tile's content stands in the world: its east-north-up frame; `None` (the
    /// world's frame) for a tile without content.
    fn world(&self, tile: TileId) -> Option<[f64; 16]> {
        self.has_content(tile)
            .then(|| EastNorthUp::new(tile).transform())
    }

    /// The zoom-`z + 1` tiles a tileset file of zoom `z` lists with their children inline,
    /// when `z + 1` has content (13 under the file of 12); otherwise its children are listed
    /// directly.
    fn inline_level(&self, tile: TileId) -> bool {
        let next = TileId {
            z: tile.z + 1,
            ..tile
        };
        tile.z + 1 < self.content_zoom && self.has_content(next)
    }

    /// Where a tile's content is, from the file that lists it (`up` leads from there to
    /// `3dtiles/`).
    fn content_uri(&self, tile: TileId, up: &str) -> String {
        let (z, x, y) = (tile.z, tile.x, tile.y);
        match &self.files {
            Some(suffix) => format!("{z}/{x}/{y}{suffix}"),
            None => format!("{up}{z}/{x}/{y}.glb{}", self.query),
        }
    }

    /// The tiles one zoom below `tile` that meet the coverage.
    fn quarters(&self, tile: TileId) -> Vec<TileId> {
        (0..2)
            .flat_map(|dy| (0..2).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| TileId {
                z: tile.z + 1,
                x: tile.x * 2 + dx,
                y: tile.y * 2 + dy,
            })
            .filter(|&t| self.meets_coverage(t))
            .collect()
    }

    /// The tile's region, or `None` when its ground is unknown and such tiles are not listed.
    fn region(&self, tile: TileId, heights: Heights<'_>) -> Option<[f64; 6]> {
        let range = match heights(tile) {
            Some(range) => range,
            None if self.list_unknown => UNKNOWN_HEIGHTS,
            None => return None,
        };
        Some(region_over(tile, range))
    }

    /// A tile entry, placed relative to `parent` (the world of the tile that lists it): a
    /// content tile with its content; a tile with a tileset file pointing at it (its own
    /// content is that file's root's); a tile listed inline with its content and children. `up`
    /// leads from the file that lists it to `3dtiles/`. `None` for a tile not listed.
    fn entry(
        &self,
        tile: TileId,
        parent: Option<[f64; 16]>,
        up: &str,
        heights: Heights<'_>,
    ) -> Option<Value> {
        let region = self.region(tile, heights)?;
        let world = self.world(tile);
        let mut entry = json!({
            "boundingVolume": {"region": region},
            "geometricError": self.error_of(tile),
            "refine": "REPLACE",
        });
        if let Some(transform) = relative(parent, world) {
            entry["transform"] = json!(transform);
        }
        if self.files.is_none() && self.has_tileset(tile) {
            let (z, x, y) = (tile.z, tile.x, tile.y);
            entry["content"] = json!({"uri": format!("{up}{z}/{x}/{y}.json{}", self.query)});
            return Some(entry);
        }
        if self.has_content(tile) {
            entry["content"] = json!({ "uri": self.content_uri(tile, up) });
        }
        if tile.z < self.content_zoom {
            let children: Vec<Value> = self
                .quarters(tile)
                .into_iter()
                .filter_map(|t| self.entry(t, world, up, heights))
                .collect();
            entry["boundingVolume"]["region"] = json!(enclosing(Some(region), &children));
            entry["children"] = json!(children);
        }
        Some(entry)
    }

    fn asset() -> Value {
        json!({
            "version": "1.1",
            "generator": concat!("terrastitch ", env!("CARGO_PKG_VERSION")),
        })
    }

    /// `/tileset.json`: a root over the coverage whose children are the top level's tiles.
    /// `at` is where the file is served: [`Root::Top`] (`/tileset.json`) or [`Root::InFolder`]
    /// (`/3dtiles/tileset.json`, next to the files it names).
    pub fn root(&self, heights: Heights<'_>, at: Root) -> Value {
        let up = match at {
            Root::Top => "3dtiles/",
            Root::InFolder => "",
        };
        let top = self.top_zoom();
        let tiles = self.covered_at(top);
        let children: Vec<Value> = tiles
            .iter()
            .filter_map(|&t| self.entry(t, None, up, heights))
            .collect();
        let region = enclosing(None, &children).unwrap_or([0.0; 6]);
        // The root has no content: while it is not opened nothing is drawn. Its error is a
        // top tile's whole ground size, so it opens while that tile is more than a few pixels
        // on screen (about 150 km away for a zoom-12 tile on a 600-pixel-high view).
        let error = tiles.first().map_or(0.0, |&t| ground_size(top, t));
        Self::document(region, error, None, children)
    }

    /// A tileset file: a root over `children`, with content when given.
    fn document(
        region: [f64; 6],
        error: f64,
        content: Option<String>,
        children: Vec<Value>,
    ) -> Value {
        let mut document = json!({
            "asset": Self::asset(),
            "geometricError": error,
            "root": {
                "boundingVolume": {"region": region},
                "geometricError": error,
                "refine": "REPLACE",
                "children": children
            }
        });
        if let Some(uri) = content {
            document["root"]["content"] = json!({ "uri": uri });
        }
        document
    }

    /// `/3dtiles/{z}/{x}/{y}.json`: the tile (with its content, placed by the entry that points
    /// here), and the tiles `LEVEL_STEP` zooms below it (through the zoom between, inline,
    /// where that zoom has content).
    pub fn subtree(&self, tile: TileId, heights: Heights<'_>) -> Value {
        let error = self.error_of(tile);
        let world = self.world(tile);
        // From `3dtiles/{z}/{x}/{y}.json` back to `3dtiles/`.
        let up = "../../";
        let below = match self.inline_level(tile) {
            true => self.quarters(tile),
            false => self.children(tile),
        };
        let children: Vec<Value> = below
            .into_iter()
            .filter_map(|t| self.entry(t, world, up, heights))
            .collect();
        let own = self
            .region(tile, heights)
            .unwrap_or_else(|| region_over(tile, UNKNOWN_HEIGHTS));
        let region = enclosing(Some(own), &children).unwrap_or(own);
        let content = self.has_content(tile).then(|| self.content_uri(tile, up));
        Self::document(region, error, content, children)
    }
}

/// The ground size of a zoom-`z` tile at `tile`'s latitude, metres.
fn ground_size(z: u8, tile: TileId) -> f64 {
    let latitude = (tile.bounds().north + tile.bounds().south) / 2.0;
    TileId { z, x: 0, y: 0 }.size_m() * latitude.to_radians().cos()
}

/// The transform that places a frame `own` (column-major; `None` for the world's) inside
/// `parent`'s: `parent⁻¹ · own`, for a 3D Tiles tile whose parent's transform applies to it.
/// Both are rigid (a rotation and a translation), so the inverse is the transposed rotation.
/// `None` when the frames are the same.
fn relative(parent: Option<[f64; 16]>, own: Option<[f64; 16]>) -> Option<[f64; 16]> {
    let identity = {
        let mut m = [0.0; 16];
        m[0] = 1.0;
        m[5] = 1.0;
        m[10] = 1.0;
        m[15] = 1.0;
        m
    };
    if parent == own {
        return None;
    }
    let p = parent.unwrap_or(identity);
    let c = own.unwrap_or(identity);
    // Column j of the rotation is m[4j..4j + 3]; the translation is m[12..15].
    let column = |m: &[f64; 16], j: usize| [m[4 * j], m[4 * j + 1], m[4 * j + 2]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut out = identity;
    for j in 0..4 {
        let v = match j {
            3 => {
                let (t, o) = (column(&c, 3), column(&p, 3));
                [t[0] - o[0], t[1] - o[1], t[2] - o[2]]
            }
            _ => column(&c, j),
        };
        for i in 0..3 {
            out[4 * j + i] = dot(column(&p, i), v);
        }
    }
    Some(out)
}

/// The region of a tile over ground from `low` to `high`, widened for what is under and on it.
fn region_over(tile: TileId, (low, high): (f64, f64)) -> [f64; 6] {
    let b = tile.bounds();
    [
        b.west.to_radians(),
        b.south.to_radians(),
        b.east.to_radians(),
        b.north.to_radians(),
        low - BELOW_GROUND_M,
        high + ABOVE_GROUND_M,
    ]
}

/// The smallest region holding `start` and the regions of `children`.
fn enclosing(start: Option<[f64; 6]>, children: &[Value]) -> Option<[f64; 6]> {
    let mut out = start;
    for child in children {
        let r = &child["boundingVolume"]["region"];
        let Some(r) = (0..6).map(|i| r[i].as_f64()).collect::<Option<Vec<f64>>>() else {
            continue;
        };
        out = Some(match out {
            None => [r[0], r[1], r[2], r[3], r[4], r[5]],
            Some(o) => [
                o[0].min(r[0]),
                o[1].min(r[1]),
                o[2].max(r[2]),
                o[3].max(r[3]),
                o[4].min(r[4]),
                o[5].max(r[5]),
            ],
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn monaco() -> Plan {
        Plan {
            content_zoom: 14,
            coverage: vec!["7.40,43.72,7.44,43.75".parse().unwrap()],
            query: String::new(),
            list_unknown: false,
            parent_content: false,
            files: None,
        }
    }

    fn flat(_: TileId) -> Option<(f64, f64)> {
        Some((0.0, 160.0))
    }

    /// The root has no content of its own: a client that does not open it draws nothing. At
    /// CesiumJS's and 3DTilesRendererJS's default of 16 pixels, on a 600-pixel-high view with
    /// a 60° field, it opens from 100 km away.
    #[test]
    fn the_root_opens_from_as_far_as_its_top_tiles_show() {
        let root = monaco().root(&flat, Root::Top);
        let error = root["root"]["geometricError"].as_f64().unwrap();
        let distance: f64 = 100_000.0;
        let pixels = error * 600.0 / (distance * 2.0 * 30f64.to_radians().tan());
        assert!(pixels > 16.0, "{pixels} pixels at {distance} m");
    }

    #[test]
    fn the_root_lists_the_parents_of_the_content_and_they_list_the_content() {
        let plan = monaco();
        assert_eq!(plan.top_zoom(), 12);
        let root = plan.root(&flat, Root::Top);
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
    fn tiles_of_unknown_ground_are_left_out_and_parents_hold_their_children() {
        let mut plan = monaco();
        let parent = TileId {
            z: 12,
            x: 2132,
            y: 1493,
        };
        let missing = TileId {
            z: 14,
            x: 8529,
            y: 5973,
        };
        // The parent's own range says less than a child's: its region still holds the child.
        let heights = |t: TileId| match (t.z, t == missing) {
            (_, true) => None,
            (14, false) => Some((-5.0, 900.0)),
            _ => Some((0.0, 100.0)),
        };
        let subtree = plan.subtree(parent, &heights);
        let children = subtree["root"]["children"].as_array().unwrap();
        let uris: Vec<&str> = children
            .iter()
            .map(|c| c["content"]["uri"].as_str().unwrap())
            .collect();
        assert!(!uris.iter().any(|u| u.contains("8529/5973")), "{uris:?}");
        assert_eq!(uris.len(), plan.children(parent).len() - 1);
        let region = &subtree["root"]["boundingVolume"]["region"];
        assert_eq!(region[4], -5.0 - BELOW_GROUND_M);
        assert_eq!(region[5], 900.0 + ABOVE_GROUND_M);
        // Where SRTM files are fetched on demand, the tile is listed with a wide range.
        plan.list_unknown = true;
        let subtree = plan.subtree(parent, &heights);
        let children = subtree["root"]["children"].as_array().unwrap();
        assert_eq!(children.len(), plan.children(parent).len());
    }

    #[test]
    fn a_large_coverage_starts_further_up() {
        let plan = Plan {
            content_zoom: 14,
            coverage: vec!["5.0,43.0,8.0,45.0".parse().unwrap()],
            query: "?compress=meshopt".to_string(),
            list_unknown: false,
            parent_content: false,
            files: None,
        };
        let top = plan.top_zoom();
        assert!(top < 12 && (14 - top) % LEVEL_STEP == 0, "{top}");
        assert!(plan.covered_at(top).len() as u64 <= ROOT_CHILDREN);
        let root = plan.root(&flat, Root::Top);
        let uri = root["root"]["children"][0]["content"]["uri"]
            .as_str()
            .unwrap();
        assert!(uri.ends_with(".json?compress=meshopt"), "{uri}");
        // A level that is not a tileset level, or a tile outside the data, has no file.
        assert!(!plan.has_tileset(TileId { z: 13, x: 0, y: 0 }));
        assert!(!plan.has_tileset(TileId { z: top, x: 0, y: 0 }));
    }

    fn matrix_product(a: &[f64; 16], b: &[f64; 16]) -> [f64; 16] {
        let mut out = [0.0; 16];
        for col in 0..4 {
            for row in 0..4 {
                out[4 * col + row] = (0..4).map(|k| a[4 * k + row] * b[4 * col + k]).sum();
            }
        }
        out
    }

    fn transform_of(entry: &Value) -> [f64; 16] {
        let values: Vec<f64> = entry["transform"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        values.try_into().unwrap()
    }

    #[test]
    fn parents_carry_content_placed_through_their_ancestors_frames() {
        let mut plan = monaco();
        plan.parent_content = true;
        let parent = TileId {
            z: 12,
            x: 2132,
            y: 1493,
        };
        let subtree = plan.subtree(parent, &flat);
        let root = &subtree["root"];
        assert_eq!(root["content"]["uri"], "../../12/2132/1493.glb");
        let world12 = EastNorthUp::new(parent).transform();
        let quarters = root["children"].as_array().unwrap();
        assert!(!quarters.is_empty());
        let mut leaves = 0;
        for quarter in quarters {
            let uri = quarter["content"]["uri"].as_str().unwrap();
            assert!(
                uri.starts_with("../../13/") && uri.ends_with(".glb"),
                "{uri}"
            );
            let error13 = quarter["geometricError"].as_f64().unwrap();
            assert!(error13 > 0.0 && error13 < root["geometricError"].as_f64().unwrap());
            let world13 = matrix_product(&world12, &transform_of(quarter));
            for leaf in quarter["children"].as_array().unwrap() {
                assert_eq!(leaf["geometricError"], 0.0);
                let uri = leaf["content"]["uri"].as_str().unwrap();
                let parts: Vec<u32> = uri
                    .trim_start_matches("../../")
                    .trim_end_matches(".glb")
                    .split('/')
                    .map(|p| p.parse().unwrap())
                    .collect();
                let tile = TileId {
                    z: parts[0] as u8,
                    x: parts[1],
                    y: parts[2],
                };
                assert_eq!(tile.z, 14);
                // Placed through both parents, the leaf stands where its own frame is.
                let placed = matrix_product(&world13, &transform_of(leaf));
                let own = EastNorthUp::new(tile).transform();
                for (a, b) in placed.iter().zip(own) {
                    assert!((a - b).abs() < 1e-6, "{placed:?} against {own:?}");
                }
                leaves += 1;
            }
        }
        assert_eq!(leaves, plan.children(parent).len());
        // The file of 10 lists the tiles of 12 by their files, placed inside its own frame.
        let ten = plan.subtree(
            TileId {
                z: 10,
                x: 533,
                y: 373,
            },
            &flat,
        );
        assert_eq!(ten["root"]["content"]["uri"], "../../10/533/373.glb");
        let entry = &ten["root"]["children"][0];
        assert!(entry["content"]["uri"].as_str().unwrap().ends_with(".json"));
        let uri = entry["content"]["uri"].as_str().unwrap();
        let parts: Vec<u32> = uri
            .trim_start_matches("../../")
            .trim_end_matches(".json")
            .split('/')
            .map(|p| p.parse().unwrap())
            .collect();
        let child = TileId {
            z: parts[0] as u8,
            x: parts[1],
            y: parts[2],
        };
        let world10 = EastNorthUp::new(TileId {
            z: 10,
            x: 533,
            y: 373,
        })
        .transform();
        let placed = matrix_product(&world10, &transform_of(entry));
        let own = EastNorthUp::new(child).transform();
        assert!(placed.iter().zip(own).all(|(a, b)| (a - b).abs() < 1e-6));
    }

    #[test]
    fn a_directory_tileset_lists_every_content_file_in_one_document() {
        let mut plan = monaco();
        plan.files = Some(".enu-meshopt.glb".to_string());
        let root = plan.root(&flat, Root::InFolder);
        let mut uris = Vec::new();
        let mut stack = vec![&root["root"]];
        while let Some(tile) = stack.pop() {
            if let Some(uri) = tile["content"]["uri"].as_str() {
                assert!(!uri.ends_with(".json"), "{uri}");
                uris.push(uri.to_string());
            }
            stack.extend(tile["children"].as_array().into_iter().flatten());
        }
        let expected = TileRange::covering(14, &plan.coverage[0]);
        assert_eq!(uris.len() as u64, expected.len());
        for tile in expected.tiles() {
            let uri = format!("14/{}/{}.enu-meshopt.glb", tile.x, tile.y);
            assert!(uris.contains(&uri), "{uri} not in {uris:?}");
        }
    }
}
