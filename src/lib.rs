//! retrace: a ray tracer for animation that re-traces only what changed.
//!
//! Embree finds the hits ([`accel::embree`]); this crate owns the cameras,
//! shading, and the reuse algorithms of Gage & Semwal (Panimation, RSVP) and
//! Jevans (OSTC).

pub mod accel;
pub mod geometry;
pub mod ray;
pub mod camera;
pub mod scene;
pub mod bench;
pub mod output;
pub mod render;
pub mod shade;
