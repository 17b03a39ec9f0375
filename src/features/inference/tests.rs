use super::*;

fn way(id: i64) -> ElementRef {
    ElementRef {
        element_type: ElementType::Way,
        id,
    }
}

/// A `w` × `d` metre rectangle at a place, its long side east–west.
fn rectangle(at: LonLat, w: f64, d: f64) -> Vec<LonLat> {
    let east = 111_320.0 * at.lat.to_radians().cos();
    let north = 110_540.0;
    let corner = |x: f64, y: f64| LonLat {
        lon: at.lon + x / east,
        lat: at.lat + y / north,
    };
    vec![
        corner(0.0, 0.0),
        corner(w, 0.0),
        corner(w, d),
        corner(0.0, d),
        corner(0.0, 0.0),
    ]
}

/// A regular polygon of `n` corners and radius `r` metres.
fn round(at: LonLat, n: usize, r: f64) -> Vec<LonLat> {
    let east = 111_320.0 * at.lat.to_radians().cos();
    let north = 110_540.0;
    (0..=n)
        .map(|i| {
            let a = std::f64::consts::TAU * (i % n) as f64 / n as f64;
            LonLat {
                lon: at.lon + r * a.cos() / east,
                lat: at.lat + r * a.sin() / north,
            }
        })
        .collect()
}

const BAVARIA: LonLat = LonLat {
    lon: 11.3,
    lat: 48.2,
};
const LIECHTENSTEIN: LonLat = LonLat {
    lon: 9.52,
    lat: 47.14,
};
const MONACO: LonLat = LonLat {
    lon: 7.42,
    lat: 43.73,
};
const HARRISBURG: LonLat = LonLat {
    lon: -76.88,
    lat: 40.27,
};

#[test]
fn places_fall_in_their_regions() {
    assert_eq!(Region::of(BAVARIA), Region::CentralEurope);
    assert_eq!(Region::of(LIECHTENSTEIN), Region::Alpine);
    assert_eq!(Region::of(MONACO), Region::Mediterranean);
    assert_eq!(Region::of(HARRISBURG), Region::NorthAmerica);
    assert_eq!(
        Region::of(LonLat {
            lon: 139.7,
            lat: 35.7
        }),
        Region::Other
    );
}

#[test]
fn a_footprint_measures_its_area_corners_and_elongation() {
    let f = Footprint::of(&rectangle(BAVARIA, 12.0, 9.0)).unwrap();
    assert!((f.area_m2 - 108.0).abs() < 0.5, "{f:?}");
    assert_eq!(f.corners, 4);
    assert!(f.rectilinear);
    assert!((f.elongation - 12.0 / 9.0).abs() < 0.01, "{f:?}");
    let hall = Footprint::of(&round(BAVARIA, 40, 30.0)).unwrap();
    assert_eq!(
        hall.corners, 0,
        "a 40-gon bends by 9° at each corner: {hall:?}"
    );
    let octagon = Footprint::of(&round(BAVARIA, 8, 10.0)).unwrap();
    assert_eq!(octagon.corners, 8);
    assert!(!octagon.rectilinear);
    assert!(Footprint::of(&rectangle(BAVARIA, 1.0, 1.0)[..2]).is_none());
}

/// The share of `n` untagged houses at `at` that get a pitched roof.
fn pitched_share(at: LonLat, building: &str, w: f64, d: f64) -> f64 {
    let footprint = Footprint::of(&rectangle(at, w, d)).unwrap();
    let region = Region::of(at);
    let pitched = (1..=1000)
        .filter(|&id| roof(building, &footprint, None, region, way(id)).shape != RoofShape::Flat)
        .count();
    pitched as f64 / 1000.0
}

#[test]
fn small_houses_are_mostly_pitched_and_industry_is_flat() {
    for at in [BAVARIA, LIECHTENSTEIN, HARRISBURG] {
        let share = pitched_share(at, "yes", 12.0, 9.0);
        assert!(share >= 0.85, "{at:?}: {share}");
        let share = pitched_share(at, "house", 12.0, 9.0);
        assert!(share >= 0.85, "{at:?}: {share}");
    }
    let share = pitched_share(MONACO, "house", 12.0, 9.0);
    assert!((0.6..0.9).contains(&share), "{share}");
    assert_eq!(pitched_share(BAVARIA, "industrial", 12.0, 9.0), 0.0);
    assert_eq!(pitched_share(BAVARIA, "retail", 30.0, 20.0), 0.0);
}

#[test]
fn a_detached_house_gets_a_gable_and_a_region_its_pitch() {
    let footprint = Footprint::of(&rectangle(BAVARIA, 12.0, 8.0)).unwrap();
    let shapes: Vec<RoofShape> = (1..=200)
        .map(|id| roof("detached", &footprint, None, Region::CentralEurope, way(id)).shape)
        .collect();
    let gabled = shapes.iter().filter(|s| **s == RoofShape::Gabled).count();
    assert!(gabled > 120, "{gabled} of 200 gabled");
    let pitch = |region| {
        (1..=200)
            .map(|id| roof("detached", &footprint, None, region, way(id)).pitch_deg)
            .filter(|p| *p > 0.0)
            .sum::<f64>()
            / 200.0
    };
    assert!(pitch(Region::CentralEurope) > pitch(Region::Mediterranean) + 10.0);
}

#[test]
fn a_forty_corner_hall_a_tall_block_and_a_large_yes_stay_flat() {
    let hall = Footprint::of(&round(BAVARIA, 40, 30.0)).unwrap();
    let house = Footprint::of(&rectangle(BAVARIA, 12.0, 9.0)).unwrap();
    let big = Footprint::of(&rectangle(BAVARIA, 40.0, 20.0)).unwrap();
    let region = Region::CentralEurope;
    for id in 1..=100 {
        assert_eq!(
            roof("industrial", &hall, None, region, way(id)).shape,
            RoofShape::Flat
        );
        assert_eq!(
            roof("yes", &house, Some(30.0), region, way(id)).shape,
            RoofShape::Flat
        );
        assert_eq!(
            roof("yes", &big, None, region, way(id)).shape,
            RoofShape::Flat
        );
    }
    let many = Footprint::of(&round(BAVARIA, 14, 10.0)).unwrap();
    assert_eq!(
        roof("house", &many, None, region, way(7)).shape,
        RoofShape::Flat,
        "14 corners"
    );
}

#[test]
fn an_outline_without_square_corners_is_hipped_rather_than_gabled() {
    let octagon = Footprint::of(&round(BAVARIA, 8, 7.0)).unwrap();
    for id in 1..=200 {
        let shape = roof("house", &octagon, None, Region::Alpine, way(id)).shape;
        assert!(
            matches!(shape, RoofShape::Hipped | RoofShape::Flat),
            "{shape:?}"
        );
    }
}

#[test]
fn the_same_building_gets_the_same_roof_and_levels_every_time() {
    let footprint = Footprint::of(&rectangle(LIECHTENSTEIN, 11.0, 9.0)).unwrap();
    let first = roof("yes", &footprint, None, Region::Alpine, way(4242));
    let first_levels = levels("yes", &footprint, Region::Alpine, Some(way(4242)));
    for _ in 0..3 {
        assert_eq!(
            roof("yes", &footprint, None, Region::Alpine, way(4242)),
            first
        );
        assert_eq!(
            levels("yes", &footprint, Region::Alpine, Some(way(4242))),
            first_levels
        );
    }
    // Another element kind with the same number draws apart.
    let node = ElementRef {
        element_type: ElementType::Relation,
        id: 4242,
    };
    assert_ne!(draw(way(4242), 1), draw(node, 1));
    assert!((0.0..1.0).contains(&draw(way(-5), 9)));
}

#[test]
fn houses_have_levels_by_region_and_sheds_keep_their_type_height() {
    let house = Footprint::of(&rectangle(HARRISBURG, 14.0, 10.0)).unwrap();
    let annex = Footprint::of(&rectangle(HARRISBURG, 6.0, 5.0)).unwrap();
    for id in 1..=100 {
        let n = levels("house", &house, Region::NorthAmerica, Some(way(id))).unwrap();
        assert!((1..=2).contains(&n), "{n}");
        assert_eq!(
            levels("yes", &annex, Region::NorthAmerica, Some(way(id))),
            Some(1)
        );
        assert_eq!(
            levels("garage", &annex, Region::NorthAmerica, Some(way(id))),
            None
        );
        let flats = levels("apartments", &house, Region::Mediterranean, Some(way(id))).unwrap();
        assert!((5..=8).contains(&flats), "{flats}");
    }
}

#[test]
fn a_field_barn_of_a_few_square_metres_has_one_storey_and_a_farm_building_one_or_two() {
    let hut = Footprint::of(&rectangle(BAVARIA, 4.5, 4.0)).unwrap();
    let barn = Footprint::of(&rectangle(BAVARIA, 20.0, 12.0)).unwrap();
    let mut two = 0;
    for id in 1..=100 {
        for building in ["barn", "stable"] {
            assert_eq!(
                levels(building, &hut, Region::Alpine, Some(way(id))),
                Some(1)
            );
            let n = levels(building, &barn, Region::Alpine, Some(way(id))).unwrap();
            assert!((1..=2).contains(&n), "{n}");
            two += usize::from(n == 2);
        }
    }
    assert!(two > 0);
}

#[test]
fn a_row_takes_one_style_without_variation_and_its_ridge_along_the_row() {
    let house = Footprint::of(&rectangle(BAVARIA, 6.0, 10.0)).unwrap();
    let roofs: Vec<InferredRoof> = (0..3)
        .map(|_| row_roof("house", &house, None, Region::CentralEurope, 12.0))
        .collect();
    assert!(roofs.windows(2).all(|w| w[0] == w[1]));
    assert_eq!(roofs[0].shape, RoofShape::Gabled);
    assert_eq!(roofs[0].direction_deg, Some(12.0));
    for (building, region) in [
        ("apartments", Region::Mediterranean),
        ("garage", Region::CentralEurope),
        ("retail", Region::Alpine),
    ] {
        let roof = row_roof(building, &house, None, region, 0.0);
        assert_eq!(roof.shape, RoofShape::Flat, "{building} in {region:?}");
    }
    // Levels without variation: the middle of the region's range, the same for every house.
    let levels_of = |id| levels("house", &house, Region::CentralEurope, id);
    assert_eq!(levels_of(None), levels_of(None));
    assert!(levels_of(None).is_some());
}
