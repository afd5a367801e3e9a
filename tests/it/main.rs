//! The integration tests, one binary: a module per area. Shared fixtures
//! (every backend, the bit-exact harness, running the binary) live in
//! `common`.

#[macro_use]
mod common;

mod animate;
mod antialiasing;
mod area_lights;
mod bump_maps;
mod cli;
mod cli_limits;
mod cli_messages;
mod cutouts;
mod docs;
mod exr;
mod extremes;
mod farm;
mod fuzz;
mod glass;
mod glossy;
mod interrupt;
mod layers;
mod lens;
mod mesh_lights;
mod motion_blur;
mod moving_spheres;
mod normals;
mod obj_exporters;
mod obj_input;
mod ostc;
mod output_folders;
mod pan_strata;
mod ray_cones;
mod render;
mod rsvp;
mod scene_errors;
mod still_split;
mod textures;
mod tga;
mod tradeoff;
mod validate;
mod validate_seeds;
mod view;
mod view_memory;
