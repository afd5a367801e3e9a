//! retrace: a ray tracer for animation that re-traces only what changed.
//!
//! Embree finds the hits ([`accel::embree`]); this crate owns the cameras,
//! shading, and the reuse algorithms of Gage & Semwal (Panimation, RSVP) and
//! Jevans (OSTC).

#![deny(unsafe_code)]

pub mod accel;
pub mod camera;
pub mod chunk;
pub mod color;
pub mod farm;
pub mod frame_loop;
pub mod geometry;
pub mod lab;
pub mod metrics;
pub mod output;
pub mod pool;
pub mod ray;
pub mod render;
pub mod reuse;
pub mod rng;
pub mod sampling;
pub mod scene;
pub mod shade;
pub mod texture;
pub mod timeline;
pub mod view;
pub mod voxel;
