//! The Embree backend of [`Intersector`]: scene objects become Embree
//! geometries, and still objects are split off into a scene of their own
//! when that makes moves cheaper ([`StillSplit`]).
//!
//! Promises:
//! - Every object is attached under its index in the object list, so a hit
//!   names its object directly. Planes are left out:
//!   [`Accelerator`](crate::accel::Accelerator) tests them for every backend.
//! - A sphere placed by a transform is the world-space sphere
//!   [`placed_sphere`] gives, as for every backend; a transform that would
//!   not keep it round is an error, not a silently different sphere.
//! - Split or not, the hits are the same: the still scene is traced first
//!   and the moving scene sees the ray as the still one left it.

use glam::Affine3A;

use super::trace::{intersect1, intersect8, occluded1, occluded8};
use super::{CommittedScene, Device, EmbreeError, SceneBuilder};
use crate::accel::{moving_sphere, placed_sphere, Intersector};
use crate::geometry::{Object, Placement, Shape, Sphere};
use crate::ray::{Hit, HitPacket, LaneMask, Ray, RayPacket};

/// The Embree backend: one geometry per scene object, attached under the
/// object's index so a hit names its object directly. A sphere placed by a
/// transform is attached as the world-space sphere [`placed_sphere`] gives;
/// other objects placed by a transform get a child scene of their own,
/// placed by an instance transform.
///
/// When objects move, committing their scene rebuilds its BVH over every
/// object in it. So once the still geometry is big enough that rebuilding it
/// costs more than a second Embree call per ray (see
/// [`SPLIT_MIN_STILL_PRIMITIVES`]), the still objects get a scene of their
/// own, committed once and traced first; the moving scene is traced after it
/// and rebuilt alone.
pub struct EmbreeIntersector {
    /// The objects that move, and the still ones unless they were split off.
    scene: CommittedScene,
    /// The still objects, when split off.
    still: Option<CommittedScene>,
    /// Spheres placed by a transform, in their own space: where a move
    /// places them from.
    placed_spheres: Vec<(u32, Sphere)>,
}

/// Still primitives from which a scene with moving objects keeps them in a
/// scene of their own. A commit's cost grows with the triangles in the
/// scene it rebuilds, so beside big still geometry every move pays for
/// rebuilding all of it; the split costs every frame a box test per packet
/// and a second call for the packets near the moving objects. Below this
/// the split costs more than the commits it saves: small scenes stay in
/// one scene.
pub const SPLIT_MIN_STILL_PRIMITIVES: usize = 10_000;

/// Whether still objects go into a scene of their own.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StillSplit {
    /// Split when objects move and the still ones hold at least
    /// [`SPLIT_MIN_STILL_PRIMITIVES`] primitives.
    Auto,
    Always,
    Never,
}

impl EmbreeIntersector {
    pub fn build(objects: &[Object]) -> Result<EmbreeIntersector, EmbreeError> {
        Self::build_with(objects, StillSplit::Auto)
    }

    pub fn build_with(
        objects: &[Object],
        split: StillSplit,
    ) -> Result<EmbreeIntersector, EmbreeError> {
        let device = Device::new()?;
        let moves = |object: &Object| !matches!(object.placement, Placement::World);
        let blurs = |object: &Object| matches!(object.placement, Placement::Moving(_));
        let still_primitives: usize = objects
            .iter()
            .filter(|object| !moves(object))
            .map(|object| match &object.shape {
                Shape::Mesh(mesh) => mesh.triangles.len(),
                Shape::Sphere(_) => 1,
                Shape::Plane(_) => 0,
            })
            .sum();
        let split = still_primitives > 0
            && objects.iter().any(moves)
            && match split {
                StillSplit::Auto => {
                    still_primitives >= SPLIT_MIN_STILL_PRIMITIVES || objects.iter().any(blurs)
                }
                StillSplit::Always => true,
                StillSplit::Never => false,
            };
        let mut top = SceneBuilder::new(&device)?;
        let mut still = if split {
            Some(SceneBuilder::new(&device)?)
        } else {
            None
        };
        let mut placed_spheres = Vec::new();
        for (id, object) in objects.iter().enumerate() {
            let id = id as u32;
            match (&object.placement, &object.shape) {
                (Placement::World, shape) => {
                    attach_shape(still.as_mut().unwrap_or(&mut top), id, shape)?
                }
                (Placement::Instance(_) | Placement::Moving(_), Shape::Plane(_)) => {}
                (Placement::Instance(transform), Shape::Sphere(sphere)) => {
                    let placed =
                        placed_sphere(sphere, transform).ok_or_else(|| not_round(id, transform))?;
                    top.attach_sphere(id, placed.center, placed.radius)?;
                    placed_spheres.push((id, *sphere));
                }
                (Placement::Moving(motion), Shape::Sphere(sphere)) => {
                    let moving = moving_sphere(sphere, motion)
                        .ok_or_else(|| not_round(id, &motion.poses[0]))?;
                    top.attach_moving_sphere(id, &moving)?;
                    placed_spheres.push((id, *sphere));
                }
                (Placement::Instance(transform), shape) => {
                    let mut child = SceneBuilder::new(&device)?;
                    attach_shape(&mut child, 0, shape)?;
                    top.attach_instance(id, child.commit()?, transform)?;
                }
                (Placement::Moving(motion), shape) => {
                    let mut child = SceneBuilder::new(&device)?;
                    attach_shape(&mut child, 0, shape)?;
                    top.attach_moving_instance(id, child.commit()?, motion)?;
                }
            }
        }
        Ok(EmbreeIntersector {
            scene: top.commit()?,
            still: still.map(SceneBuilder::commit).transpose()?,
            placed_spheres,
        })
    }

    /// Whether the still objects were split off into a scene of their own.
    pub fn still_split(&self) -> bool {
        self.still.is_some()
    }

    /// Places each object of `moves` (built with a transform) by its new
    /// transform, then re-commits the scene once.
    pub fn move_objects(&mut self, moves: &[(u32, Affine3A)]) -> Result<(), EmbreeError> {
        let placements: Vec<(u32, Placement)> = moves
            .iter()
            .map(|&(object, xf)| (object, Placement::Instance(xf)))
            .collect();
        self.place_objects(&placements)
    }

    /// Places each object of `placements` (built with the same kind of
    /// placement: a transform, or a motion over the shutter), then
    /// re-commits the scene once.
    pub fn place_objects(&mut self, placements: &[(u32, Placement)]) -> Result<(), EmbreeError> {
        let mut edit = self.scene.edit();
        for (object, placement) in placements {
            let sphere = self.placed_spheres.iter().find(|(id, _)| id == object);
            match (placement, sphere) {
                (Placement::Instance(transform), Some((_, sphere))) => {
                    let placed = placed_sphere(sphere, transform)
                        .ok_or_else(|| not_round(*object, transform))?;
                    edit.move_sphere(*object, placed.center, placed.radius)?;
                }
                (Placement::Moving(motion), Some((_, sphere))) => {
                    let moving = moving_sphere(sphere, motion)
                        .ok_or_else(|| not_round(*object, &motion.poses[0]))?;
                    edit.move_moving_sphere(*object, &moving)?;
                }
                (Placement::Instance(transform), None) => {
                    edit.set_instance_transform(*object, transform)?
                }
                (Placement::Moving(motion), None) => edit.set_instance_motion(*object, motion)?,
                (Placement::World, _) => {
                    return Err(EmbreeError {
                        code: "invalid argument",
                        message: format!("object {object}: a move needs a transform or a motion"),
                    })
                }
            }
        }
        edit.commit()
    }

    pub fn scene_mut(&mut self) -> &mut CommittedScene {
        &mut self.scene
    }

    pub fn device(&self) -> &Device {
        self.scene.device()
    }

    /// The scenes a ray is traced through, still geometry first (it is
    /// the bigger one, so the moving scene then sees a shorter ray).
    fn stack(&self) -> ([&CommittedScene; 2], usize) {
        match &self.still {
            Some(still) => ([still, &self.scene], 2),
            None => ([&self.scene, &self.scene], 1),
        }
    }
}

fn not_round(object: u32, transform: &Affine3A) -> EmbreeError {
    EmbreeError {
        code: "invalid argument",
        message: format!("object {object}: a sphere's transform must keep it round: {transform:?}"),
    }
}

/// Planes are left out: [`crate::accel::Accelerator`] tests them for every
/// backend.
fn attach_shape(scene: &mut SceneBuilder, id: u32, shape: &Shape) -> Result<(), EmbreeError> {
    match shape {
        Shape::Mesh(mesh) if !mesh.triangles.is_empty() => {
            scene.attach_triangles(id, &mesh.positions, &mesh.triangles, mesh.cutout.as_ref())
        }
        Shape::Mesh(_) | Shape::Plane(_) => Ok(()),
        Shape::Sphere(sphere) => scene.attach_sphere(id, sphere.center, sphere.radius),
    }
}

impl Intersector for EmbreeIntersector {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let (scenes, n) = self.stack();
        intersect1(&scenes[..n], ray)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let (scenes, n) = self.stack();
        occluded1(&scenes[..n], ray)
    }

    fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        let (scenes, n) = self.stack();
        intersect8(&scenes[..n], rays, mask, hits)
    }

    fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        let (scenes, n) = self.stack();
        occluded8(&scenes[..n], rays, mask)
    }
}
