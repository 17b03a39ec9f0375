use super::*;

const ZOOM: u8 = 14;

/// The zoom-14 cell of a place.
fn cell(lon: f64, lat: f64) -> (u32, u32) {
    let b = bounds_of(&[LonLat { lon, lat }]).unwrap();
    cells_of(&b, f64::from(1u32 << ZOOM)).next().unwrap()
}

fn moved_node(from: (f64, f64), to: (f64, f64)) -> NodeEdit {
    NodeEdit {
        id: 1,
        at: None,
        old: Some(LonLat {
            lon: from.0,
            lat: from.1,
        }),
        new: Some((
            LonLat {
                lon: to.0,
                lat: to.1,
            },
            codec::Writer::default(),
        )),
    }
}

#[test]
fn a_moved_node_reaches_the_cells_of_both_its_places_and_nothing_between() {
    let plan = Plan {
        nodes: vec![moved_node((7.42, 43.73), (8.42, 44.73))],
        ..Plan::default()
    };
    let mut reach = Reach::new(ZOOM);
    plan.reach(&mut reach);
    assert!(reach.cells.contains(&cell(7.42, 43.73)));
    assert!(reach.cells.contains(&cell(8.42, 44.73)));
    assert!(reach.cells.len() <= 8, "{:?}", reach.cells);
}

#[test]
fn a_changed_way_reaches_the_cells_its_line_crosses_not_its_box() {
    // A degree to the north-east: about 45 cells along and 45 across at zoom 14.
    let way = crate::osm::fixture::way(
        7,
        &[("highway", "residential")],
        &[(1, 7.40, 43.70), (2, 8.40, 44.70)],
    );
    let plan = Plan {
        ways: [(
            7,
            WayEdit {
                old: Some(way),
                new: None,
                named: None,
                missing: Vec::new(),
            },
        )]
        .into(),
        ..Plan::default()
    };
    let mut reach = Reach::new(ZOOM);
    plan.reach(&mut reach);
    let (a, b) = (cell(7.40, 43.70), cell(8.40, 44.70));
    let across = (a.0.abs_diff(b.0) + 1) as usize;
    let down = (a.1.abs_diff(b.1) + 1) as usize;
    assert!(reach.cells.contains(&a) && reach.cells.contains(&b));
    assert!(
        reach.cells.len() <= 3 * (across + down),
        "{} cells of a box of {}",
        reach.cells.len(),
        across * down
    );
}

#[test]
fn a_reached_cell_expires_its_tile_and_the_neighbours_whose_query_reads_it() {
    let mut reach = Reach::new(ZOOM);
    reach.point(Some(LonLat {
        lon: 7.4255,
        lat: 43.7396,
    }));
    let (x, y) = cell(7.4255, 43.7396);
    let tiles = reach.tiles(ZOOM, 1e-4);
    assert!(tiles.contains(&TileId { z: ZOOM, x, y }));
    assert!(tiles.len() <= 9, "{tiles:?}");
    assert!(tiles
        .iter()
        .all(|t| t.x.abs_diff(x) <= 1 && t.y.abs_diff(y) <= 1));
}
