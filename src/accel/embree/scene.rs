//! Embree scenes: built ([`SceneBuilder`]: triangle meshes, sphere points,
//! instances of other scenes), committed ([`CommittedScene`]), and moved
//! after commit ([`SceneEdit`]).
//!
//! Promises:
//! - Rays are traced only on a [`CommittedScene`]; a scene keeps its device
//!   alive (Embree reference counts), and an instancing scene keeps its
//!   child scenes, so nothing dangles. Each scene reference is released
//!   exactly once.
//! - Geometries are attached under the ids the caller gives; only those
//!   attached as movable (spheres, instances) can be moved, and any other
//!   id is refused before Embree sees it (Debian's Embree asserts on an
//!   unknown id, aborting the process).
//! - Moving geometry ([`CommittedScene::edit`]) needs `&mut`, so no ray is in
//!   flight while the scene is re-committed. A sphere moves by rewriting its
//!   one vertex in place (it stays a plain sphere of the top-level scene:
//!   an instance, even of one small sphere, makes every ray of a small
//!   scene far dearer); meshes move as instances, so their own triangles
//!   are never rebuilt. An edit re-commits the scene once, however many
//!   objects it moved, and an edit dropped early still commits. That
//!   commit rebuilds the BVH over every object of its scene, spheres moved
//!   in place or instances alike, so its cost grows with the scene.
//!   RTC_SCENE_FLAG_DYNAMIC, RTC_BUILD_QUALITY_REFIT on the spheres, or
//!   both with MEDIUM scene quality do not shorten it, and at our HIGH
//!   scene quality the first two leave tracing unchanged, so none is set.
//!   Big still geometry beside moving objects therefore gets a scene of its
//!   own, committed once ([`super::EmbreeIntersector`]).
//! - A committed scene's `bounds` are re-read after every commit, so the
//!   box test that lets a packet skip a scene (`trace.rs`) sees the moves.

use std::ffi::c_void;
use std::sync::Arc;

use glam::{Affine3A, Vec3};

use super::{callback_panic, sys};
use super::{Device, EmbreeError};
use crate::geometry::{Aabb, Cutout, Motion, MovingSphere, Sphere, MOTION_STEPS};

/// A scene being built. Attach geometry, then [`SceneBuilder::commit`].
pub struct SceneBuilder {
    raw: sys::RTCScene,
    device: Device,
    children: Vec<CommittedScene>,
    movable: MovableIds,
    /// The cut-outs its geometries' filters read, each in an `Arc` of its
    /// own so it stays put as the list grows.
    cutouts: Vec<Arc<Cutout>>,
}

/// The ids of a scene's geometries that can move after commit, checked
/// before Embree is asked (Debian's Embree asserts, aborting the process,
/// on an unknown id).
#[derive(Default)]
struct MovableIds {
    instances: Vec<u32>,
    spheres: Vec<u32>,
    moving_instances: Vec<u32>,
    moving_spheres: Vec<u32>,
}

impl SceneBuilder {
    pub fn new(device: &Device) -> Result<SceneBuilder, EmbreeError> {
        // SAFETY: creating a scene on a live device.
        let raw = unsafe { sys::rtcNewScene(device.raw()) };
        device.take_error()?;
        if raw.is_null() {
            return Err(EmbreeError {
                code: "unknown",
                message: "rtcNewScene returned null".into(),
            });
        }
        // SAFETY: `raw` is a live scene.
        unsafe {
            sys::rtcSetSceneBuildQuality(raw, sys::RTCBuildQuality::RTC_BUILD_QUALITY_HIGH);
            // Robust mode: without it Embree's triangle test loses rays
            // through shared edges and vertices of closed meshes.
            sys::rtcSetSceneFlags(raw, sys::RTCSceneFlags::RTC_SCENE_FLAG_ROBUST);
        }
        let builder = SceneBuilder {
            raw,
            device: device.clone(),
            children: Vec::new(),
            movable: MovableIds::default(),
            cutouts: Vec::new(),
        };
        callback_panic::resume();
        Ok(builder)
    }

    pub(super) fn new_geometry(
        &self,
        kind: sys::RTCGeometryType,
    ) -> Result<sys::RTCGeometry, EmbreeError> {
        // SAFETY: creating a geometry on a live device.
        let geometry = unsafe { sys::rtcNewGeometry(self.device.raw(), kind) };
        self.device.take_error()?;
        Ok(geometry)
    }

    /// Fills a new Embree-owned buffer (Embree pads it as its SIMD loads need).
    fn fill_buffer<T: Copy>(
        &self,
        geometry: sys::RTCGeometry,
        kind: sys::RTCBufferType,
        format: sys::RTCFormat,
        items: &[T],
    ) -> Result<(), EmbreeError> {
        self.fill_slot(geometry, kind, 0, format, items)
    }

    /// [`SceneBuilder::fill_buffer`] for buffer `slot` (a time step's).
    fn fill_slot<T: Copy>(
        &self,
        geometry: sys::RTCGeometry,
        kind: sys::RTCBufferType,
        slot: u32,
        format: sys::RTCFormat,
        items: &[T],
    ) -> Result<(), EmbreeError> {
        // SAFETY: `geometry` is live; Embree allocates `items.len()` elements
        // of `size_of::<T>()` bytes (plus padding) and returns that memory.
        let ptr = unsafe {
            sys::rtcSetNewGeometryBuffer(
                geometry,
                kind,
                slot,
                format,
                std::mem::size_of::<T>(),
                items.len(),
            )
        };
        self.device.take_error()?;
        if ptr.is_null() {
            return Err(EmbreeError {
                code: "out of memory",
                message: "rtcSetNewGeometryBuffer returned null".into(),
            });
        }
        // SAFETY: `ptr` points to at least `items.len()` writable elements of
        // T's size; Embree aligns buffers to 16 bytes (T is f32/u32 based).
        unsafe { std::ptr::copy_nonoverlapping(items.as_ptr(), ptr as *mut T, items.len()) };
        Ok(())
    }

    fn attach(&mut self, geometry: sys::RTCGeometry, id: u32) -> Result<(), EmbreeError> {
        // SAFETY: `geometry` is live and fully set up; the scene takes its own
        // reference, so ours is released right after.
        unsafe {
            sys::rtcCommitGeometry(geometry);
            sys::rtcAttachGeometryByID(self.raw, geometry, id);
            sys::rtcReleaseGeometry(geometry);
        }
        self.device.take_error()
    }

    /// A triangle mesh; with a `cutout`, hits where it lets rays through
    /// are skipped.
    pub fn attach_triangles(
        &mut self,
        id: u32,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        cutout: Option<&Cutout>,
    ) -> Result<(), EmbreeError> {
        let geometry = self.new_geometry(sys::RTCGeometryType::RTC_GEOMETRY_TYPE_TRIANGLE)?;
        let vertices: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
        self.fill_buffer(
            geometry,
            sys::RTCBufferType::RTC_BUFFER_TYPE_VERTEX,
            sys::RTCFormat::RTC_FORMAT_FLOAT3,
            &vertices,
        )?;
        self.fill_buffer(
            geometry,
            sys::RTCBufferType::RTC_BUFFER_TYPE_INDEX,
            sys::RTCFormat::RTC_FORMAT_UINT3,
            triangles,
        )?;
        if let Some(cutout) = cutout {
            let kept = Arc::new(cutout.clone());
            // SAFETY: `geometry` is a live triangle geometry; the `Arc` is
            // kept by this builder and then by its committed scene, which
            // releases the Embree scene (and so the geometry) before
            // dropping its fields.
            unsafe { super::cutout::set_filters(geometry, &kept) };
            self.cutouts.push(kept);
        }
        self.attach(geometry, id)
    }

    pub fn attach_sphere(&mut self, id: u32, center: Vec3, radius: f32) -> Result<(), EmbreeError> {
        let geometry = self.new_geometry(sys::RTCGeometryType::RTC_GEOMETRY_TYPE_SPHERE_POINT)?;
        self.fill_buffer(
            geometry,
            sys::RTCBufferType::RTC_BUFFER_TYPE_VERTEX,
            sys::RTCFormat::RTC_FORMAT_FLOAT4,
            &[sphere_vertex(center, radius)],
        )?;
        self.attach(geometry, id)?;
        self.movable.spheres.push(id);
        Ok(())
    }

    /// Places `child` into this scene through `transform`; hits on it report
    /// `id` as their object.
    pub fn attach_instance(
        &mut self,
        id: u32,
        child: CommittedScene,
        transform: &Affine3A,
    ) -> Result<(), EmbreeError> {
        let geometry = self.new_geometry(sys::RTCGeometryType::RTC_GEOMETRY_TYPE_INSTANCE)?;
        // SAFETY: both handles are live; Embree keeps its own reference to the
        // child scene, and we keep `child` too for as long as this scene.
        unsafe { sys::rtcSetGeometryInstancedScene(geometry, child.raw) };
        set_transform(geometry, 0, transform);
        self.children.push(child);
        self.attach(geometry, id)?;
        self.movable.instances.push(id);
        Ok(())
    }

    /// [`SceneBuilder::attach_instance`] for an instance moving while the
    /// shutter is open: a transform per time step, which Embree
    /// interpolates at each ray's time.
    pub fn attach_moving_instance(
        &mut self,
        id: u32,
        child: CommittedScene,
        motion: &Motion,
    ) -> Result<(), EmbreeError> {
        let geometry = self.new_geometry(sys::RTCGeometryType::RTC_GEOMETRY_TYPE_INSTANCE)?;
        // SAFETY: as in `attach_instance`; the time steps are set before
        // any transform is.
        unsafe {
            sys::rtcSetGeometryInstancedScene(geometry, child.raw);
            sys::rtcSetGeometryTimeStepCount(geometry, MOTION_STEPS as u32);
        }
        set_motion(geometry, motion);
        self.children.push(child);
        self.attach(geometry, id)?;
        self.movable.moving_instances.push(id);
        Ok(())
    }

    /// A sphere moving while the shutter is open: a vertex buffer per time
    /// step, which Embree interpolates at each ray's time.
    pub fn attach_moving_sphere(
        &mut self,
        id: u32,
        sphere: &MovingSphere,
    ) -> Result<(), EmbreeError> {
        let geometry = self.new_geometry(sys::RTCGeometryType::RTC_GEOMETRY_TYPE_SPHERE_POINT)?;
        // SAFETY: `geometry` is live and has no buffers yet.
        unsafe { sys::rtcSetGeometryTimeStepCount(geometry, MOTION_STEPS as u32) };
        for (slot, step) in sphere.steps.iter().enumerate() {
            self.fill_slot(
                geometry,
                sys::RTCBufferType::RTC_BUFFER_TYPE_VERTEX,
                slot as u32,
                sys::RTCFormat::RTC_FORMAT_FLOAT4,
                &[sphere_vertex(step.center, step.radius)],
            )?;
        }
        self.attach(geometry, id)?;
        self.movable.moving_spheres.push(id);
        Ok(())
    }

    pub fn commit(self) -> Result<CommittedScene, EmbreeError> {
        // SAFETY: `raw` is live and no ray is traced on it while committing
        // (we own it exclusively).
        unsafe { sys::rtcCommitScene(self.raw) };
        self.device.take_error()?;
        let this = std::mem::ManuallyDrop::new(self);
        // SAFETY: moving fields out of a ManuallyDrop that is never used again,
        // so the scene is released exactly once (by CommittedScene).
        let (device, children, movable, cutouts) = unsafe {
            (
                std::ptr::read(&this.device),
                std::ptr::read(&this.children),
                std::ptr::read(&this.movable),
                std::ptr::read(&this.cutouts),
            )
        };
        let scene = CommittedScene {
            raw: this.raw,
            device,
            _children: children,
            movable,
            _cutouts: cutouts,
            bounds: scene_bounds(this.raw),
        };
        callback_panic::resume();
        Ok(scene)
    }
}

impl Drop for SceneBuilder {
    fn drop(&mut self) {
        // SAFETY: a builder dropped before commit owns its scene reference.
        unsafe { sys::rtcReleaseScene(self.raw) };
    }
}

/// The bounds of a committed scene; empty for a scene with no geometry.
fn scene_bounds(scene: sys::RTCScene) -> Aabb {
    let mut bounds = sys::RTCBounds::default();
    // SAFETY: `scene` is live and committed; `bounds` is a valid, 16-byte
    // aligned RTCBounds (bindgen's layout test checks the alignment).
    unsafe { sys::rtcGetSceneBounds(scene, &mut bounds) };
    Aabb {
        min: Vec3::new(bounds.lower_x, bounds.lower_y, bounds.lower_z),
        max: Vec3::new(bounds.upper_x, bounds.upper_y, bounds.upper_z),
    }
}

/// A sphere point's vertex: centre and radius (RTC_FORMAT_FLOAT4).
fn sphere_vertex(center: Vec3, radius: f32) -> [f32; 4] {
    [center.x, center.y, center.z, radius]
}

/// Every time step's transform of a moving instance.
fn set_motion(geometry: sys::RTCGeometry, motion: &Motion) {
    for (step, pose) in motion.poses.iter().enumerate() {
        set_transform(geometry, step as u32, pose);
    }
}

/// Time step `step`'s transform (0 for an instance that does not move
/// while the shutter is open).
fn set_transform(geometry: sys::RTCGeometry, step: u32, transform: &Affine3A) {
    // Column-major 3x4: the three basis columns, then the translation.
    let m = transform.matrix3;
    let t = transform.translation;
    let columns: [f32; 12] = [
        m.x_axis.x, m.x_axis.y, m.x_axis.z, m.y_axis.x, m.y_axis.y, m.y_axis.z, m.z_axis.x,
        m.z_axis.y, m.z_axis.z, t.x, t.y, t.z,
    ];
    // SAFETY: `geometry` is a live instance with more than `step` time
    // steps; Embree copies the 12 floats.
    unsafe {
        sys::rtcSetGeometryTransform(
            geometry,
            step,
            sys::RTCFormat::RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR,
            columns.as_ptr() as *const c_void,
        )
    };
}

/// A committed scene: the only kind rays can be traced on.
pub struct CommittedScene {
    pub(super) raw: sys::RTCScene,
    device: Device,
    _children: Vec<CommittedScene>,
    movable: MovableIds,
    /// The cut-outs its geometries' filters read. Dropped after `Drop`
    /// has released the scene, so no filter outlives its cut-out.
    _cutouts: Vec<Arc<Cutout>>,
    /// Embree's bounds of everything in the scene as last committed: a
    /// packet that misses them skips the scene when it is traced second.
    pub(super) bounds: Aabb,
}

// SAFETY: Embree allows concurrent rtcIntersect*/rtcOccluded* calls on a
// committed scene; mutation (`edit`) takes `&mut self`.
unsafe impl Sync for CommittedScene {}
// SAFETY: the scene handle may be used and released from any thread.
unsafe impl Send for CommittedScene {}

impl Drop for CommittedScene {
    fn drop(&mut self) {
        // SAFETY: we own one reference to the scene.
        unsafe { sys::rtcReleaseScene(self.raw) };
    }
}

impl CommittedScene {
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// Starts moving geometry; [`SceneEdit::commit`] re-commits the scene
    /// once for every move made through the edit.
    pub fn edit(&mut self) -> SceneEdit<'_> {
        SceneEdit {
            scene: self,
            committed: false,
        }
    }

    /// Moves instance `id` and re-commits; only the top level is rebuilt.
    pub fn set_instance_transform(
        &mut self,
        id: u32,
        transform: &Affine3A,
    ) -> Result<(), EmbreeError> {
        let mut edit = self.edit();
        edit.set_instance_transform(id, transform)?;
        edit.commit()
    }
}

/// Moves geometry of a committed scene. Rays cannot be traced meanwhile (the
/// edit borrows the scene mutably); [`SceneEdit::commit`] makes the moves
/// visible. An edit dropped without `commit` still commits, so the scene is
/// never left half updated; an error there surfaces at the next call that
/// checks for errors.
pub struct SceneEdit<'a> {
    scene: &'a mut CommittedScene,
    committed: bool,
}

impl SceneEdit<'_> {
    fn unknown(kind: &str, id: u32) -> EmbreeError {
        EmbreeError {
            code: "invalid argument",
            message: format!("no {kind} with id {id}"),
        }
    }

    /// Places instance `id` by `transform`.
    pub fn set_instance_transform(
        &mut self,
        id: u32,
        transform: &Affine3A,
    ) -> Result<(), EmbreeError> {
        if !self.scene.movable.instances.contains(&id) {
            return Err(Self::unknown("instance", id));
        }
        // SAFETY: the edit borrows the scene mutably, so no ray is in flight;
        // `id` names an attached instance, which the scene keeps alive.
        unsafe {
            let geometry = sys::rtcGetGeometry(self.scene.raw, id);
            set_transform(geometry, 0, transform);
            sys::rtcCommitGeometry(geometry);
        }
        self.scene.device.take_error()
    }

    /// Gives sphere `id` (attached with [`SceneBuilder::attach_sphere`]) a
    /// new centre and radius, written into its vertex buffer in place.
    pub fn move_sphere(&mut self, id: u32, center: Vec3, radius: f32) -> Result<(), EmbreeError> {
        if !self.scene.movable.spheres.contains(&id) {
            return Err(Self::unknown("sphere", id));
        }
        self.write_sphere(id, 0, center, radius)
    }

    /// Gives moving instance `id` (attached with
    /// [`SceneBuilder::attach_moving_instance`]) its motion over a new
    /// shutter.
    pub fn set_instance_motion(&mut self, id: u32, motion: &Motion) -> Result<(), EmbreeError> {
        if !self.scene.movable.moving_instances.contains(&id) {
            return Err(Self::unknown("moving instance", id));
        }
        // SAFETY: as in `set_instance_transform`; the instance was made
        // with MOTION_STEPS time steps.
        unsafe {
            let geometry = sys::rtcGetGeometry(self.scene.raw, id);
            set_motion(geometry, motion);
            sys::rtcCommitGeometry(geometry);
        }
        self.scene.device.take_error()
    }

    /// Gives moving sphere `id` (attached with
    /// [`SceneBuilder::attach_moving_sphere`]) its spheres over a new
    /// shutter.
    pub fn move_moving_sphere(
        &mut self,
        id: u32,
        sphere: &MovingSphere,
    ) -> Result<(), EmbreeError> {
        if !self.scene.movable.moving_spheres.contains(&id) {
            return Err(Self::unknown("moving sphere", id));
        }
        for (slot, Sphere { center, radius }) in sphere.steps.iter().enumerate() {
            self.write_sphere(id, slot as u32, *center, *radius)?;
        }
        Ok(())
    }

    /// Rewrites sphere `id`'s vertex in buffer `slot` and commits the
    /// geometry.
    fn write_sphere(
        &mut self,
        id: u32,
        slot: u32,
        center: Vec3,
        radius: f32,
    ) -> Result<(), EmbreeError> {
        let vertex_buffer = sys::RTCBufferType::RTC_BUFFER_TYPE_VERTEX;
        // SAFETY: as above; `id` names a sphere geometry whose vertex buffer
        // in `slot` Embree allocated when it was attached, with one FLOAT4
        // element.
        let data = unsafe {
            let geometry = sys::rtcGetGeometry(self.scene.raw, id);
            (
                geometry,
                sys::rtcGetGeometryBufferData(geometry, vertex_buffer, slot),
            )
        };
        self.scene.device.take_error()?;
        let (geometry, vertex) = data;
        if vertex.is_null() {
            return Err(Self::unknown("sphere vertex buffer for", id));
        }
        // SAFETY: `vertex` points to that one element (16 bytes, aligned by
        // Embree to 16); nothing reads it until the commit below and the
        // scene's, both after this write.
        unsafe {
            std::ptr::write(vertex as *mut [f32; 4], sphere_vertex(center, radius));
            sys::rtcUpdateGeometryBuffer(geometry, vertex_buffer, slot);
            sys::rtcCommitGeometry(geometry);
        }
        self.scene.device.take_error()
    }

    /// Re-commits the scene: the moves take effect.
    pub fn commit(mut self) -> Result<(), EmbreeError> {
        self.committed = true;
        commit_scene(self.scene)
    }
}

impl Drop for SceneEdit<'_> {
    fn drop(&mut self) {
        if !self.committed {
            // SAFETY: as in `commit_scene`. An error stays in the device's
            // slot for the next check, and a panic in the error callback in
            // this thread's slot (no panic out of `drop`).
            unsafe { sys::rtcCommitScene(self.scene.raw) };
            self.scene.bounds = scene_bounds(self.scene.raw);
        }
    }
}

fn commit_scene(scene: &mut CommittedScene) -> Result<(), EmbreeError> {
    // SAFETY: `&mut` guarantees no concurrent tracing on the scene.
    unsafe { sys::rtcCommitScene(scene.raw) };
    scene.device.take_error()?;
    scene.bounds = scene_bounds(scene.raw);
    callback_panic::resume();
    Ok(())
}
