//! Rules of where doors stand: at the entrances mapped on a building's outline, in its wall,
//! facing out of the building.

use super::*;

/// A house 16 m square in the tile's middle (its north-west corner at `(0.48, 0.48)`) with an
/// entrance tagged `tags` in the middle of its south wall and another node in its north wall.
fn house_with_entrance(tags: &[(&str, &str)]) -> Fixture {
    let side = 16.0 * metre();
    let (w, n) = (0.48, 0.48);
    let (e, s) = (w + side, n + side);
    let mut fixture = Fixture::default();
    fixture
        .way(
            &[("building", "house")],
            &[
                (w, n),
                ((w + e) / 2.0, n),
                (e, n),
                (e, s),
                ((w + e) / 2.0, s),
                (w, s),
                (w, n),
            ],
        )
        .join((w, n))
        .tag_node(((w + e) / 2.0, s), tags);
    fixture
}

/// The doors of a fixture: where each stands (metres east and south of the house's south
/// wall's middle) and which way it faces (east and south parts of a unit vector).
fn doors(fixture: &Fixture) -> Vec<([f64; 2], [f64; 2])> {
    let set = collected(fixture);
    let projection = terrastitch::features::Projection::new(TILE.z);
    let metre = projection.metres(1.0, at(0.5, 0.5).lat);
    let side = 16.0 * self::metre();
    let middle = projection.point(at(0.48 + side / 2.0, 0.48 + side));
    set.objects
        .iter()
        .filter(|o| o.kind == ObjectKind::Door)
        .map(|o| {
            let off = [(o.at[0] - middle[0]) / metre, (o.at[1] - middle[1]) / metre];
            // A model faces north; turned by θ it faces (-sin θ, -cos θ).
            (off, [-o.rotation.sin(), -o.rotation.cos()])
        })
        .collect()
}

#[test]
fn a_door_stands_in_the_wall_at_a_mapped_entrance_facing_out() {
    let found = doors(&house_with_entrance(&[("entrance", "main")]));
    assert_eq!(found.len(), 1, "{found:?}");
    let ([east, south], [face_east, face_south]) = found[0];
    assert!(
        east.abs() < 0.01 && (south - 0.05).abs() < 0.01,
        "{found:?}"
    );
    assert!(
        face_east.abs() < 1e-6 && (face_south - 1.0).abs() < 1e-6,
        "{found:?}"
    );
    let tile = drawn(
        &house_with_entrance(&[("entrance", "main")]),
        &terrain(|_, _| 100.0),
    );
    assert!(tile.instanced.contains("door"), "{:?}", tile.instanced);
}

#[test]
fn an_entrance_tagged_no_or_off_any_building_has_no_door() {
    assert!(doors(&house_with_entrance(&[("entrance", "no")])).is_empty());
    let mut fixture = Fixture::default();
    fixture.node(&[("entrance", "yes")], (0.3, 0.3));
    assert!(doors(&fixture).is_empty());
}
