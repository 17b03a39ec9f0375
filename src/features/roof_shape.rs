//! The roof shapes the mesh stage can build, by their `roof:shape` names.

use tracing::debug;

/// A roof the mesh stage can build (Simple 3D Buildings' `roof:shape` values).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum RoofShape {
    Flat,
    /// One plane sloping down towards `roof:direction`.
    Skillion,
    /// Slopes on the long sides, vertical gables at the ends of each wing.
    Gabled,
    /// Every side slopes up to the ridges (the straight skeleton raised).
    Hipped,
    /// Gabled ends cut off by a small hip at the top.
    HalfHipped,
    /// Gabled, with one end hipped (the one `roof:direction` names).
    SideHipped,
    /// Gabled, with one end half-hipped.
    SideHalfHipped,
    /// Hipped ends with a small gable at the top (dutch hip).
    HippedAndGabled,
    /// Straight faces from every side to a point over the middle (also `cone`).
    Pyramidal,
    /// A quarter circle in section, up to a point over the middle.
    Dome,
    /// Bulging out past the walls, then drawn in to a point.
    Onion,
    /// A barrel vault: a half ellipse across the footprint.
    Round,
    /// Gabled, with steep lower slopes and shallow upper ones.
    Gambrel,
    /// Hipped, with steep lower slopes and shallow upper ones.
    Mansard,
    /// Gabled with the ridge off the middle: a long slope towards `roof:direction`.
    Saltbox,
    /// Teeth across the footprint: long slopes and steep glazed faces.
    Sawtooth,
    /// Two slopes falling to a valley in the middle.
    Butterfly,
}

impl RoofShape {
    /// The shape a `roof:shape` value names, `None` for a value we do not know.
    pub fn from_tag(value: &str) -> Option<RoofShape> {
        Some(match value {
            "flat" => RoofShape::Flat,
            "skillion" | "lean_to" => RoofShape::Skillion,
            "gabled" => RoofShape::Gabled,
            "hipped" => RoofShape::Hipped,
            "half-hipped" | "half_hipped" => RoofShape::HalfHipped,
            "side_hipped" => RoofShape::SideHipped,
            "side_half-hipped" => RoofShape::SideHalfHipped,
            "hipped-and-gabled" | "dutch" => RoofShape::HippedAndGabled,
            "pyramidal" | "cone" => RoofShape::Pyramidal,
            "dome" => RoofShape::Dome,
            "onion" => RoofShape::Onion,
            "round" => RoofShape::Round,
            "gambrel" => RoofShape::Gambrel,
            "mansard" => RoofShape::Mansard,
            "saltbox" | "gabled_height_moved" => RoofShape::Saltbox,
            "sawtooth" => RoofShape::Sawtooth,
            "butterfly" => RoofShape::Butterfly,
            "crosspitched" => {
                debug!("crosspitched roof drawn hipped");
                RoofShape::Hipped
            }
            _ => return None,
        })
    }

    /// The `roof:shape` value that names it.
    pub fn tag(self) -> &'static str {
        match self {
            RoofShape::Flat => "flat",
            RoofShape::Skillion => "skillion",
            RoofShape::Gabled => "gabled",
            RoofShape::Hipped => "hipped",
            RoofShape::HalfHipped => "half-hipped",
            RoofShape::SideHipped => "side_hipped",
            RoofShape::SideHalfHipped => "side_half-hipped",
            RoofShape::HippedAndGabled => "hipped-and-gabled",
            RoofShape::Pyramidal => "pyramidal",
            RoofShape::Dome => "dome",
            RoofShape::Onion => "onion",
            RoofShape::Round => "round",
            RoofShape::Gambrel => "gambrel",
            RoofShape::Mansard => "mansard",
            RoofShape::Saltbox => "saltbox",
            RoofShape::Sawtooth => "sawtooth",
            RoofShape::Butterfly => "butterfly",
        }
    }

    /// Every shape.
    pub const ALL: [RoofShape; 17] = [
        RoofShape::Flat,
        RoofShape::Skillion,
        RoofShape::Gabled,
        RoofShape::Hipped,
        RoofShape::HalfHipped,
        RoofShape::SideHipped,
        RoofShape::SideHalfHipped,
        RoofShape::HippedAndGabled,
        RoofShape::Pyramidal,
        RoofShape::Dome,
        RoofShape::Onion,
        RoofShape::Round,
        RoofShape::Gambrel,
        RoofShape::Mansard,
        RoofShape::Saltbox,
        RoofShape::Sawtooth,
        RoofShape::Butterfly,
    ];
}
