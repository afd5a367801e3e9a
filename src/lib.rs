//! retrace: a ray tracer for animation that re-traces only what changed.
//!
//! Embree finds the hits ([`accel::embree`]); this crate owns the cameras,
//! shading, and the reuse algorithms of Gage & Semwal (Panimation, RSVP) and
//! Jevans (OSTC).
//!
//! The features `lab` (measurements and plots), `view` (the window) and
//! `farm` (Slurm) add modules the renderer does not need; all are on by
//! default.

#![deny(unsafe_code)]

pub mod accel;
pub mod aov;
pub mod camera;
pub mod chunk;
pub mod clock;
pub mod color;
#[cfg(feature = "farm")]
pub mod farm;
pub mod frame_loop;
pub mod geometry;
#[cfg(feature = "lab")]
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
pub mod verify;
#[cfg(feature = "view")]
pub mod view;
pub mod voxel;
