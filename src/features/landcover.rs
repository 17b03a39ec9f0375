//! Land cover: areas whose tags say what covers the ground (forest, grass, fields, sand, rock,
//! built-up land, parking, pitches, parks), drawn as ground materials (thesis §2.3.4).
//!
//! Land cover lies under roads, railways and water and over the default ground. Where two land
//! covers overlap, the smaller area wins: a pitch inside a park, a park inside a residential
//! area, each keeps its own material.

use super::{Area, FeatureClass, FeatureSet, Projection};
use crate::osm::Tags;

/// What covers the ground of an area.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Cover {
    Forest,
    Grass,
    Meadow,
    Farmland,
    Orchard,
    Vineyard,
    Scrub,
    Heath,
    Sand,
    Beach,
    BareRock,
    Wetland,
    Residential,
    Commercial,
    Industrial,
    Parking,
    Pitch,
    Park,
}

impl Cover {
    pub const ALL: [Cover; 18] = [
        Cover::Forest,
        Cover::Grass,
        Cover::Meadow,
        Cover::Farmland,
        Cover::Orchard,
        Cover::Vineyard,
        Cover::Scrub,
        Cover::Heath,
        Cover::Sand,
        Cover::Beach,
        Cover::BareRock,
        Cover::Wetland,
        Cover::Residential,
        Cover::Commercial,
        Cover::Industrial,
        Cover::Parking,
        Cover::Pitch,
        Cover::Park,
    ];

    /// The cover an area's tags describe, if any.
    pub fn from_tags(tags: &Tags) -> Option<Cover> {
        if let Some(natural) = tags.get("natural") {
            let cover = match natural {
                "wood" => Some(Cover::Forest),
                "grassland" => Some(Cover::Grass),
                "scrub" => Some(Cover::Scrub),
                "heath" => Some(Cover::Heath),
                "sand" => Some(Cover::Sand),
                "beach" => Some(Cover::Beach),
                "bare_rock" | "scree" | "shingle" => Some(Cover::BareRock),
                "wetland" => Some(Cover::Wetland),
                _ => None,
            };
            if cover.is_some() {
                return cover;
            }
        }
        if let Some(leisure) = tags.get("leisure") {
            let cover = match leisure {
                "pitch" | "track" => Some(Cover::Pitch),
                "park" | "garden" | "playground" | "dog_park" => Some(Cover::Park),
                _ => None,
            };
            if cover.is_some() {
                return cover;
            }
        }
        if tags.get("amenity") == Some("parking")
            && !matches!(
                tags.get("parking"),
                Some("underground" | "multi-storey" | "rooftop")
            )
        {
            return Some(Cover::Parking);
        }
        match tags.get("landuse")? {
            "forest" => Some(Cover::Forest),
            "grass" | "village_green" | "recreation_ground" | "cemetery" => Some(Cover::Grass),
            "meadow" => Some(Cover::Meadow),
            "farmland" | "allotments" | "greenhouse_horticulture" => Some(Cover::Farmland),
            "orchard" => Some(Cover::Orchard),
            "vineyard" => Some(Cover::Vineyard),
            "residential" => Some(Cover::Residential),
            "commercial" | "retail" => Some(Cover::Commercial),
            "industrial" | "railway" | "construction" | "brownfield" => Some(Cover::Industrial),
            _ => None,
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Cover::Forest => "forest",
            Cover::Grass => "grass",
            Cover::Meadow => "meadow",
            Cover::Farmland => "farmland",
            Cover::Orchard => "orchard",
            Cover::Vineyard => "vineyard",
            Cover::Scrub => "scrub",
            Cover::Heath => "heath",
            Cover::Sand => "sand",
            Cover::Beach => "beach",
            Cover::BareRock => "bare_rock",
            Cover::Wetland => "wetland",
            Cover::Residential => "residential",
            Cover::Commercial => "commercial",
            Cover::Industrial => "industrial",
            Cover::Parking => "parking",
            Cover::Pitch => "pitch",
            Cover::Park => "park",
        }
    }

    /// Linear base colour and roughness of the material.
    pub fn material(self) -> ([f32; 4], f32) {
        let (rgb, roughness) = match self {
            Cover::Forest => ([0.13, 0.27, 0.11], 0.95),
            Cover::Grass => ([0.30, 0.50, 0.18], 0.95),
            Cover::Meadow => ([0.40, 0.54, 0.22], 0.95),
            Cover::Farmland => ([0.56, 0.52, 0.30], 0.95),
            Cover::Orchard => ([0.33, 0.48, 0.20], 0.95),
            Cover::Vineyard => ([0.42, 0.46, 0.22], 0.95),
            Cover::Scrub => ([0.28, 0.38, 0.18], 0.95),
            Cover::Heath => ([0.44, 0.40, 0.26], 0.95),
            Cover::Sand => ([0.80, 0.72, 0.50], 0.9),
            Cover::Beach => ([0.86, 0.78, 0.58], 0.9),
            Cover::BareRock => ([0.50, 0.48, 0.45], 0.9),
            Cover::Wetland => ([0.26, 0.38, 0.30], 0.6),
            Cover::Residential => ([0.62, 0.60, 0.56], 0.9),
            Cover::Commercial => ([0.66, 0.58, 0.56], 0.9),
            Cover::Industrial => ([0.58, 0.56, 0.60], 0.9),
            Cover::Parking => ([0.40, 0.40, 0.42], 0.85),
            Cover::Pitch => ([0.24, 0.50, 0.22], 0.9),
            Cover::Park => ([0.34, 0.56, 0.24], 0.95),
        };
        ([rgb[0], rgb[1], rgb[2], 1.0], roughness)
    }
}

pub(super) fn add_area(set: &mut FeatureSet, area: &Area<'_>, projection: &Projection) {
    let Some(cover) = Cover::from_tags(area.tags) else {
        return;
    };
    // Buildings, water and roads drawn as areas are their own features, whatever else they say.
    if area.tags.is_set("building")
        || super::water::is_water_area(area.tags)
        || area.tags.get("area:highway").is_some()
    {
        return;
    }
    if let Some(surface) = set.add_area_surface(area, FeatureClass::LandCover, projection) {
        surface.cover = Some(cover);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tags_choose_the_cover() {
        let cover = |pairs: &[(&str, &str)]| Cover::from_tags(&Tags::from_pairs(pairs.to_vec()));
        assert_eq!(cover(&[("landuse", "forest")]), Some(Cover::Forest));
        assert_eq!(cover(&[("natural", "wood")]), Some(Cover::Forest));
        assert_eq!(
            cover(&[("leisure", "pitch"), ("sport", "tennis")]),
            Some(Cover::Pitch)
        );
        assert_eq!(cover(&[("amenity", "parking")]), Some(Cover::Parking));
        assert_eq!(
            cover(&[("amenity", "parking"), ("parking", "underground")]),
            None
        );
        // The more specific natural or leisure tag wins over a broad landuse.
        assert_eq!(
            cover(&[("landuse", "residential"), ("leisure", "park")]),
            Some(Cover::Park)
        );
        assert_eq!(cover(&[("landuse", "quarry_of_dreams")]), None);
        assert_eq!(cover(&[("highway", "residential")]), None);
        // Every cover has its own material name.
        let mut names: Vec<&str> = Cover::ALL.iter().map(|c| c.as_str()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Cover::ALL.len());
    }
}
