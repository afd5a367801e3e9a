//! The integration tests, one binary: a module per area. Shared fixtures
//! (every backend, the bit-exact harness, running the binary) live in
//! `common`.

#[macro_use]
mod common;

mod animate;
mod cli;
mod extremes;
mod fuzz;
mod layers;
mod moving_spheres;
mod ostc;
mod output_folders;
mod render;
mod rsvp;
mod scene_errors;
mod still_split;
mod tradeoff;
mod validate;
