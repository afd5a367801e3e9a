//! What changes in the scene between frames, and what OSTC says those
//! changes dirty: the one place where a store's samples are invalidated.
//!
//! Promises: every sample whose colour a change of an animated object or
//! light can alter is erased from the store before the next view reads it
//! (OSTC is conservative, see [`crate::reuse::ostc`]); a store that keeps
//! no OSTC restarts instead, which is always exact.

use std::time::Instant;

use crate::camera::{CameraMotion, Lens};
use crate::clock;
use crate::geometry::{Aabb, Light, Object, Placement, Shape, MOTION_STEPS};
use crate::reuse::ostc::{Footprint, Ostc};
use crate::reuse::regions::{RegionLayout, RegionSet};
use crate::reuse::{Dirty, Erasure, SampleStore};
use crate::scene::Scene;
use crate::timeline::Animation;

use crate::reuse::OstcSettings;

/// The most memory OSTC's region bits and grid may take (E3's: 1 MB). Fine
/// regions over a narrow view's whole-turn buffer, or a huge voxel grid,
/// would pass it: OSTC is then off, with the reason.
pub const OSTC_LIMIT_BYTES: f64 = 2e9;

/// Where the scene's moving parts are: what a store's samples were traced
/// with.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct ScenePose {
    /// Where each animated object is (in the order of the tracks).
    places: Vec<Place>,
    lights: Vec<Light>,
    pub(super) lens: Option<Lens>,
    /// How the camera moves while the shutter is open.
    pub(super) camera_motion: Option<CameraMotion>,
}

impl ScenePose {
    pub(super) fn of(scene: &Scene, animation: Option<&Animation>) -> ScenePose {
        let places = animation
            .into_iter()
            .flat_map(|a| &a.objects)
            .flat_map(|track| &track.objects)
            .map(|&object| {
                let object = &scene.objects[object];
                Place {
                    placement: object.placement,
                    footprint: footprint(object),
                }
            })
            .collect();
        ScenePose {
            places,
            lights: scene.lights.clone(),
            lens: scene.lens,
            camera_motion: scene.camera_motion.clone(),
        }
    }
}

/// An animated object's placement, which says whether it moved, and its
/// footprint, which says what a move dirties. The footprint alone would
/// not do with a shutter: a ball rising through one shutter and falling
/// through the next, either side of its hop's peak, covers the same
/// heights in both, at other times.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Place {
    placement: Placement,
    footprint: Footprint,
}

/// The footprints of the places that changed from `old` to `new`: where
/// each moved object was and is.
fn moves<'a>(old: &'a ScenePose, new: &'a ScenePose) -> impl Iterator<Item = [Footprint; 2]> + 'a {
    old.places
        .iter()
        .zip(&new.places)
        .filter(|(was, is)| was.placement != is.placement)
        .map(|(was, is)| [was.footprint, is.footprint])
}

/// Where an object is in the world, for OSTC.
fn footprint(object: &Object) -> Footprint {
    match (&object.shape, object.placement) {
        (Shape::Sphere(sphere), Placement::Instance(xf)) => Footprint::Ball {
            center: xf.transform_point3(sphere.center),
            // Motion is rigid: any axis gives the scale.
            radius: sphere.radius * xf.matrix3.x_axis.length(),
        },
        (Shape::Sphere(sphere), Placement::Moving(motion)) => {
            match crate::accel::moving_sphere(sphere, &motion) {
                Some(moving) => Footprint::Path {
                    centers: moving.steps.map(|s| s.center),
                    radius: moving.steps.iter().map(|s| s.radius).fold(0.0, f32::max),
                },
                None => Footprint::Box(object.world_bounds()),
            }
        }
        (Shape::Sphere(sphere), Placement::World) => Footprint::Ball {
            center: sphere.center,
            radius: sphere.radius,
        },
        _ => Footprint::Box(object.world_bounds()),
    }
}

/// Everything the animated objects of `scene` cover over the whole
/// animation (not just the frames of a run: a superset is always safe).
pub fn swept_bounds(scene: &Scene, animation: &Animation) -> Aabb {
    let mut swept = Aabb::EMPTY;
    for track in &animation.objects {
        let rest = track
            .objects
            .iter()
            .map(|&object| scene.objects[object].shape.bounds())
            .fold(Aabb::EMPTY, |a, b| a.union(b));
        if rest.is_empty() {
            continue;
        }
        for frame in 0..animation.frames {
            swept = swept.union(rest.transformed(&track.transform_at(frame)));
            // An object is placed between its poses over a shutter by
            // interpolation, which stays within the poses' boxes.
            if let Some(shutter) = &animation.shutter {
                for step in 0..MOTION_STEPS {
                    let time = shutter.instant(frame, step as f64 / (MOTION_STEPS - 1) as f64);
                    swept = swept.union(rest.transformed(&track.transform_at_time(time)));
                }
            }
        }
    }
    swept
}

/// Why OSTC, asked for, cannot be kept for a run: stores then restart
/// whenever something moves, which is exact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OstcRefusal {
    /// No voxel grid fits moving objects that reach infinity.
    UnboundedSweep,
    /// The region bits and the voxel grid would pass [`OSTC_LIMIT_BYTES`].
    TooLarge {
        regions: usize,
        region_size: (i64, i64),
        voxels: u32,
        bytes: f64,
    },
}

impl std::fmt::Display for OstcRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OstcRefusal::UnboundedSweep => write!(
                f,
                "the moving objects' swept bounds are not finite (no grid fits them)"
            ),
            OstcRefusal::TooLarge {
                regions,
                region_size: (width, height),
                voxels,
                bytes,
            } => write!(
                f,
                "its bookkeeping ({regions} regions of {width}x{height} samples, {voxels} \
                 voxels) would take {:.1} GB; the limit is {:.0} GB",
                bytes / 1e9,
                OSTC_LIMIT_BYTES / 1e9
            ),
        }
    }
}

/// OSTC bookkeeping over `layout` for the moving parts of `scene`'s
/// timeline: None when nothing but the camera moves (no grid when no
/// object moves, no light bookkeeping when no light moves); the reason
/// when it cannot be kept.
pub(super) fn build_ostc(
    scene: &Scene,
    animation: &Animation,
    settings: &OstcSettings,
    layout: RegionLayout,
) -> Result<Option<Ostc>, OstcRefusal> {
    if !animation.moves_scene() {
        return Ok(None);
    }
    let swept = (!animation.objects.is_empty()).then(|| swept_bounds(scene, animation));
    if swept.is_some_and(|b| !(b.max - b.min).is_finite()) {
        return Err(OstcRefusal::UnboundedSweep);
    }
    let mut animated_lights = vec![false; scene.lights.len()];
    for track in &animation.lights {
        animated_lights[track.light] = true;
    }
    let voxels = settings.voxels;
    let bytes = Ostc::bytes_for(layout.count(), voxels, swept.is_some());
    if bytes > OSTC_LIMIT_BYTES {
        return Err(OstcRefusal::TooLarge {
            regions: layout.count(),
            region_size: (layout.width, layout.height),
            voxels,
            bytes,
        });
    }
    Ok(Some(Ostc::new(layout, swept, voxels, &animated_lights)))
}

/// What invalidating a store cost and nulled.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Invalidation {
    pub regions: u64,
    pub samples_nulled: u64,
    pub ms: f64,
}

/// Erases from `store` every sample the change from `old` to `new` can
/// alter, as `ostc` finds them, and forgets their recorded rays (the
/// re-traced samples record them again).
pub(super) fn invalidate(
    store: &mut dyn SampleStore,
    ostc: &mut Ostc,
    old: &ScenePose,
    new: &ScenePose,
) -> Invalidation {
    let start = Instant::now();
    let layout = *ostc.layout();
    let lit = dirty_by_lights(ostc, old, new);
    let (regions, samples_nulled) = match store.erasure() {
        Erasure::Regions => {
            let mut dirty = lit;
            for footprints in moves(old, new) {
                dirty.union_with(&ostc.dirty_for(&footprints));
            }
            let nulled = store.erase(&Dirty {
                layout: &layout,
                regions: &dirty,
                groups: &[],
            });
            ostc.forget(&dirty);
            (dirty.len(), nulled)
        }
        // A moved light dirties whole regions; a moved object only the
        // groups whose rays meet it (a region holds many groups of a
        // finer level).
        Erasure::Groups => {
            let (regions, groups) = dirty_groups(ostc, old, new);
            let mut touched = regions.clone();
            touched.union_with(&lit);
            let nulled = store.erase(&Dirty {
                layout: &layout,
                regions: &lit,
                groups: &groups,
            });
            ostc.forget(&lit);
            ostc.forget_groups(&regions, &groups);
            (touched.len(), nulled)
        }
    };
    Invalidation {
        regions: regions as u64,
        samples_nulled,
        ms: clock::ms(start.elapsed()),
    }
}

/// The regions whose samples the lights' change from `old` to `new` can
/// alter.
fn dirty_by_lights(ostc: &Ostc, old: &ScenePose, new: &ScenePose) -> RegionSet {
    let mut dirty = RegionSet::empty(ostc.layout().count());
    for (index, (was, is)) in old.lights.iter().zip(&new.lights).enumerate() {
        if was != is {
            let moved = is.moved_from(was);
            dirty.union_with(&ostc.dirty_for_light(index, moved));
        }
    }
    dirty
}

/// The groups (sorted keys) whose samples the objects' moves from `old`
/// to `new` can alter, and the regions they lie in.
fn dirty_groups(ostc: &Ostc, old: &ScenePose, new: &ScenePose) -> (RegionSet, Vec<u128>) {
    let mut regions = RegionSet::empty(ostc.layout().count());
    let mut groups = Vec::new();
    for footprints in moves(old, new) {
        let (r, g) = ostc.dirty_groups_for(&footprints);
        regions.union_with(&r);
        groups.extend(g);
    }
    groups.sort_unstable();
    groups.dedup();
    (regions, groups)
}
