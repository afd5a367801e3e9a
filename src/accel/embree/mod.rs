//! Safe wrappers over Debian's Embree (3.13 or 4.x, chosen by build.rs), and
//! the Embree backend of [`Intersector`](super::Intersector). The only
//! module with `unsafe`.
//!
//! - `device.rs`: the [`Device`], and Embree's errors funnelled into
//!   `Result`s ([`EmbreeError`]).
//! - `scene.rs`: building, committing and moving scenes and instances
//!   ([`SceneBuilder`], [`CommittedScene`], [`SceneEdit`]).
//! - `trace.rs`: rays and packets in Embree's layout, and the
//!   rtcIntersect/rtcOccluded calls on a committed scene or a stack of them.
//! - `intersector.rs`: [`EmbreeIntersector`], which turns scene objects into
//!   Embree scenes, the still ones split off from the moving ones
//!   ([`StillSplit`]).
//! - `cutout.rs`: the filters that let rays through a cut-out mesh's clear
//!   texels.
//! - `callback_panic.rs`: panics in the callback Embree calls, kept from
//!   unwinding into C and raised again once the call has returned.
//! - `sys.rs`: the raw bindings build.rs generates.
//!
//! Which Embree is bound shows as `cfg(embree_version = "3")` or `"4"`;
//! only `trace.rs` (and one test) differs between the two: Embree 4 dropped
//! the intersect context argument.

mod callback_panic;
mod cutout;
mod device;
mod intersector;
mod scene;
mod sys;
#[cfg(test)]
mod tests;
mod trace;

pub use device::{Device, EmbreeError};
pub use intersector::{EmbreeIntersector, StillSplit, SPLIT_MIN_STILL_PRIMITIVES};
pub use scene::{CommittedScene, SceneBuilder, SceneEdit};
