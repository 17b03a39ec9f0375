//! Where tiles come from: the opened inputs a tile is made from ([`inputs`]), and the one step
//! from them to a tile's bytes in a format ([`pipeline`]).

pub mod inputs;
pub mod pipeline;

pub use inputs::Inputs;
