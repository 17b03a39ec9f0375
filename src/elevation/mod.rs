//! Elevations settled by a linear program (thesis chapter 4): features declare connectors and
//! constraints between them, and one robust LP ([`lp`]) chooses every elevation at once.

pub mod constraints;
pub mod ground;
pub mod lp;
pub mod road_profiles;
pub mod roads;
pub mod settled;
pub mod solutions;
pub mod steps;
pub mod structures;
pub mod water;
