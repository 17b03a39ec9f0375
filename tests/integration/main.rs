//! The integration tests, in one binary: each module is the specification of one part, run
//! over the bundled sample, hand-written fixtures, a server process or a browser. One binary
//! links the library once and lets the slow suites run beside each other.
//!
//! Run one part with its module as the filter: `cargo test --release --test integration
//! golden::`.

mod common;

mod cli;
mod cluster;
mod datum;
mod dem;
mod elevation;
mod features;
mod fetch;
mod globe;
mod golden;
mod ground_mesh;
mod hardening;
mod hostile;
mod layers;
mod lp;
mod offline;
mod overview;
mod postgres;
mod road_network;
mod roofs;
mod router;
mod rules;
mod seams;
mod server;
mod spec;
mod store;
mod structures;
mod terrain;
mod tiles;
mod update;
mod variants;
mod viewer;
