use super::*;
use crate::osm::{ElementRef, ElementType, Member, Tags};

fn row() -> Generalised {
    Generalised {
        ways: vec![Way {
            id: 7,
            tags: Tags::from_pairs([("highway", "primary")]),
            nodes: vec![1, 5, 9],
            positions: vec![
                LonLat {
                    lon: 7.123_456_7,
                    lat: 43.7,
                },
                LonLat {
                    lon: 7.2,
                    lat: 43.750_000_1,
                },
                LonLat {
                    lon: 7.3,
                    lat: 43.8,
                },
            ],
        }],
        relations: vec![Relation {
            id: 3,
            tags: Tags::from_pairs([("type", "multipolygon"), ("natural", "water")]),
            members: vec![Member {
                element: ElementRef {
                    element_type: ElementType::Way,
                    id: 7,
                },
                role: "outer".into(),
            }],
        }],
        blocks: vec![Block {
            outer: vec![[0.52, 0.36], [0.521, 0.36], [0.521, 0.361]],
            holes: vec![vec![[0.5201, 0.3601], [0.5202, 0.3601], [0.5202, 0.3602]]],
            height_m: 11.25,
        }],
    }
}

#[test]
fn a_row_reads_back_bit_for_bit() {
    let row = row();
    assert_eq!(decode(&encode(&row)), Ok(row));
    assert_eq!(
        decode(&encode(&Generalised::default())),
        Ok(Generalised::default())
    );
}

#[test]
fn a_damaged_row_is_an_error_not_a_panic() {
    let bytes = encode(&row());
    for cut in 0..bytes.len() {
        assert!(decode(&bytes[..cut]).is_err(), "cut at {cut}");
    }
    let mut longer = bytes.clone();
    longer.push(0);
    assert!(decode(&longer).is_err());
    // A count far larger than the row: refused before anything is allocated for it.
    assert!(decode(&[0xff, 0xff, 0xff, 0xff, 0x0f]).is_err());
}

#[test]
fn a_tile_has_one_ancestor_at_each_coarser_zoom() {
    let tile = TileId {
        z: 14,
        x: 8529,
        y: 5974,
    };
    assert_eq!(
        ancestor(tile, 13),
        TileId {
            z: 13,
            x: 4264,
            y: 2987
        }
    );
    assert_eq!(
        ancestor(tile, 8),
        TileId {
            z: 8,
            x: 133,
            y: 93
        }
    );
    assert_eq!(ancestor(tile, 14), tile);
}
