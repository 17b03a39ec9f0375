//! The OSM data of far views, generalised once: for each zoom far views are made at, and each
//! tile of it, the ways and relations such a view draws with their lines simplified to its
//! scale, and its buildings merged into blocks. A far tile is made from its own generalised
//! data, never from every element under it, so its cost does not grow with the data: the
//! finest far zoom is generalised from the data, each coarser one from the finer one's tiles.
//!
//! What is drawn and how it is simplified is the features' business; these are the shapes
//! the store keeps and the renderer reads.

use super::{Relation, Way};
use crate::tile::TileId;

/// A point in Web Mercator world coordinates: `0..1` west to east and north to south (a
/// tile's units divided by the tiles across at its zoom, exactly, being powers of two).
pub type WorldPoint = [f64; 2];

/// Buildings merged into one flat-roofed block.
#[derive(Debug, Clone, PartialEq)]
pub struct Block {
    pub outer: Vec<WorldPoint>,
    pub holes: Vec<Vec<WorldPoint>>,
    /// The mean height of its buildings, weighted by their area, metres.
    pub height_m: f64,
}

/// The generalised data of one far tile: ways in id order (those it draws, simplified, and the
/// members of its relations), its area relations, and the blocks whose centre it holds.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Generalised {
    pub ways: Vec<Way>,
    pub relations: Vec<Relation>,
    pub blocks: Vec<Block>,
}

/// What a far tile is generalised from.
#[derive(Debug, Clone, Copy)]
pub struct FarSource<'a> {
    pub tile: TileId,
    /// The zoom tiles are served at (the tile is above it).
    pub served_zoom: u8,
    /// The ways and relations near the tile: as mapped for the finest far zoom, else the
    /// generalised ones of the finer tiles under it and around.
    pub ways: &'a [&'a Way],
    pub relations: &'a [&'a Relation],
    /// The finer tiles' blocks; `None` when the ways are as mapped (their buildings make the
    /// blocks).
    pub blocks: Option<&'a [&'a Block]>,
}

/// Makes the generalised data of a far tile (the features' rules, handed to the store).
pub type Generalise = fn(&FarSource<'_>) -> Generalised;

/// A far tile as read from a store: its generalised data, and the coastline ways that may hold
/// the point of the coast nearest to it (which side of the coast it lies on is read from them).
#[derive(Debug, Default)]
pub struct FarTile {
    pub data: Generalised,
    pub coast: Vec<Way>,
}
