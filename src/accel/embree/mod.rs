//! Safe wrappers over Debian's Embree (3.13 or 4.x, chosen by build.rs), and
//! the Embree backend of [`Intersector`]. The only module with `unsafe`.
//!
//! Promises:
//! - Errors reported by Embree's error callback become `Result`s; the error
//!   slot is read after building calls, never per ray.
//! - Rays are traced only on a [`CommittedScene`]; a scene keeps its device
//!   alive (Embree reference counts), so nothing dangles.
//! - Moving geometry ([`CommittedScene::edit`]) needs `&mut`, so no ray is in
//!   flight while the scene is re-committed. A sphere moves by rewriting its
//!   one vertex in place (it stays a plain sphere of the top-level scene:
//!   an instance, even of one small sphere, nearly doubled the cost of every
//!   ray of the paper scene); meshes move as instances, so their own
//!   triangles are never rebuilt. An edit re-commits the scene once, however
//!   many objects it moved. That commit rebuilds the BVH over every object
//!   of its scene: measured on Embree 3.13.5, about 15 us on the paper
//!   scene but about 2 ms beside the 3674-triangle bunny, as it was with
//!   instances. RTC_SCENE_FLAG_DYNAMIC, RTC_BUILD_QUALITY_REFIT on the
//!   spheres, or both with MEDIUM scene quality did not shorten it, and at
//!   our HIGH scene quality the first two left tracing unchanged to the
//!   instruction (callgrind), so none is set. Big still geometry beside
//!   moving objects therefore gets a scene of its own, committed once
//!   ([`EmbreeIntersector`]).
//! - A stack of scenes reports exactly the nearest hit of one scene holding
//!   everything: each scene is traced with the ray as the one before left it.

mod sys;

use std::ffi::{c_char, c_void, CStr};
use std::sync::Mutex;

use glam::{Affine3A, Vec3};

use super::{placed_sphere, Intersector};
use crate::geometry::{Aabb, Object, Placement, Shape, Sphere};
use crate::ray::{lanes, Hit, HitPacket, LaneMask, Ray, RayPacket, PACKET_WIDTH};

const INVALID_ID: u32 = u32::MAX;

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("Embree error ({code}): {message}")]
pub struct EmbreeError {
    pub code: &'static str,
    pub message: String,
}

fn error_name(code: sys::RTCError) -> &'static str {
    match code {
        sys::RTCError::RTC_ERROR_NONE => "none",
        sys::RTCError::RTC_ERROR_INVALID_ARGUMENT => "invalid argument",
        sys::RTCError::RTC_ERROR_INVALID_OPERATION => "invalid operation",
        sys::RTCError::RTC_ERROR_OUT_OF_MEMORY => "out of memory",
        sys::RTCError::RTC_ERROR_UNSUPPORTED_CPU => "unsupported CPU",
        sys::RTCError::RTC_ERROR_CANCELLED => "cancelled",
        _ => "unknown",
    }
}

/// Where the error callback leaves the first error it sees.
struct ErrorSlot {
    first: Mutex<Option<EmbreeError>>,
}

unsafe extern "C" fn record_error(user: *mut c_void, code: sys::RTCError, text: *const c_char) {
    // A panic must not unwind into C: catch it and drop the report instead.
    let _ = std::panic::catch_unwind(|| {
        // SAFETY: `user` is the `ErrorSlot` registered in `Device::new`; it is
        // boxed and lives until after `rtcReleaseDevice` in `Drop`.
        let slot = unsafe { &*(user as *const ErrorSlot) };
        let message = if text.is_null() {
            String::new()
        } else {
            // SAFETY: Embree passes a NUL-terminated string valid for the call.
            unsafe { CStr::from_ptr(text) }
                .to_string_lossy()
                .into_owned()
        };
        if let Ok(mut first) = slot.first.lock() {
            first.get_or_insert(EmbreeError {
                code: error_name(code),
                message,
            });
        }
    });
}

struct DeviceInner {
    raw: sys::RTCDevice,
    errors: Box<ErrorSlot>,
}

impl Drop for DeviceInner {
    fn drop(&mut self) {
        // SAFETY: `raw` came from rtcNewDevice and this is its last Rust
        // owner; scenes hold their own `Arc` to this, so none outlives it.
        unsafe { sys::rtcReleaseDevice(self.raw) };
    }
}

// SAFETY: Embree devices are thread-safe; the error slot is behind a Mutex.
unsafe impl Send for DeviceInner {}
// SAFETY: as above.
unsafe impl Sync for DeviceInner {}

/// An Embree device. Cheap to clone (shared).
#[derive(Clone)]
pub struct Device {
    inner: std::sync::Arc<DeviceInner>,
}

impl Device {
    pub fn new() -> Result<Device, EmbreeError> {
        // SAFETY: the config is a NUL-terminated literal.
        let raw = unsafe { sys::rtcNewDevice(c"verbose=0".as_ptr()) };
        if raw.is_null() {
            // SAFETY: a null device asks for the error of device creation.
            let code = unsafe { sys::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(EmbreeError {
                code: error_name(code),
                message: "rtcNewDevice failed".into(),
            });
        }
        let errors = Box::new(ErrorSlot {
            first: Mutex::new(None),
        });
        // SAFETY: `raw` is a live device; the slot pointer stays valid for the
        // device's lifetime (both live in `DeviceInner`, released together).
        unsafe {
            sys::rtcSetDeviceErrorFunction(
                raw,
                Some(record_error),
                &*errors as *const ErrorSlot as *mut c_void,
            )
        };
        Ok(Device {
            inner: std::sync::Arc::new(DeviceInner { raw, errors }),
        })
    }

    /// Returns (and clears) the first error Embree reported since the last call.
    fn take_error(&self) -> Result<(), EmbreeError> {
        let mut first = self
            .inner
            .errors
            .first
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        match first.take() {
            Some(err) => Err(err),
            None => Ok(()),
        }
    }

    /// Embree's version as a number, e.g. 31305 for 3.13.5.
    pub fn version(&self) -> i64 {
        // SAFETY: querying a property of a live device.
        unsafe {
            sys::rtcGetDeviceProperty(
                self.inner.raw,
                sys::RTCDeviceProperty::RTC_DEVICE_PROPERTY_VERSION,
            ) as i64
        }
    }

    pub fn native_packet8(&self) -> bool {
        // SAFETY: querying a property of a live device.
        unsafe {
            sys::rtcGetDeviceProperty(
                self.inner.raw,
                sys::RTCDeviceProperty::RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED,
            ) != 0
        }
    }
}

/// A scene being built. Attach geometry, then [`SceneBuilder::commit`].
pub struct SceneBuilder {
    raw: sys::RTCScene,
    device: Device,
    children: Vec<CommittedScene>,
    movable: MovableIds,
}

/// The ids of a scene's geometries that can move after commit, checked
/// before Embree is asked (Debian's Embree asserts, aborting the process,
/// on an unknown id).
#[derive(Default)]
struct MovableIds {
    instances: Vec<u32>,
    spheres: Vec<u32>,
}

impl SceneBuilder {
    pub fn new(device: &Device) -> Result<SceneBuilder, EmbreeError> {
        // SAFETY: creating a scene on a live device.
        let raw = unsafe { sys::rtcNewScene(device.inner.raw) };
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
            // through shared edges and vertices of closed meshes (measured:
            // 44 of 3072 edge-exact rays on Debian's 3.13.5).
            sys::rtcSetSceneFlags(raw, sys::RTCSceneFlags::RTC_SCENE_FLAG_ROBUST);
        }
        Ok(SceneBuilder {
            raw,
            device: device.clone(),
            children: Vec::new(),
            movable: MovableIds::default(),
        })
    }

    fn new_geometry(&self, kind: sys::RTCGeometryType) -> Result<sys::RTCGeometry, EmbreeError> {
        // SAFETY: creating a geometry on a live device.
        let geometry = unsafe { sys::rtcNewGeometry(self.device.inner.raw, kind) };
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
        // SAFETY: `geometry` is live; Embree allocates `items.len()` elements
        // of `size_of::<T>()` bytes (plus padding) and returns that memory.
        let ptr = unsafe {
            sys::rtcSetNewGeometryBuffer(
                geometry,
                kind,
                0,
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

    pub fn attach_triangles(
        &mut self,
        id: u32,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
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
        set_transform(geometry, transform);
        self.children.push(child);
        self.attach(geometry, id)?;
        self.movable.instances.push(id);
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
        let (device, children, movable) = unsafe {
            (
                std::ptr::read(&this.device),
                std::ptr::read(&this.children),
                std::ptr::read(&this.movable),
            )
        };
        Ok(CommittedScene {
            raw: this.raw,
            device,
            _children: children,
            movable,
            bounds: scene_bounds(this.raw),
        })
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

fn set_transform(geometry: sys::RTCGeometry, transform: &Affine3A) {
    // Column-major 3x4: the three basis columns, then the translation.
    let m = transform.matrix3;
    let t = transform.translation;
    let columns: [f32; 12] = [
        m.x_axis.x, m.x_axis.y, m.x_axis.z, m.y_axis.x, m.y_axis.y, m.y_axis.z, m.z_axis.x,
        m.z_axis.y, m.z_axis.z, t.x, t.y, t.z,
    ];
    // SAFETY: `geometry` is a live instance; Embree copies the 12 floats.
    unsafe {
        sys::rtcSetGeometryTransform(
            geometry,
            0,
            sys::RTCFormat::RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR,
            columns.as_ptr() as *const c_void,
        )
    };
}

/// A committed scene: the only kind rays can be traced on.
pub struct CommittedScene {
    raw: sys::RTCScene,
    device: Device,
    _children: Vec<CommittedScene>,
    movable: MovableIds,
    /// Embree's bounds of everything in the scene as last committed: a
    /// packet that misses them skips the scene when it is traced second.
    bounds: Aabb,
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

#[cfg(embree_version = "3")]
// Which optional fields exist depends on how Embree was configured
// (instStackSize, minWidthDistanceFactor), hence the catch-all update.
#[allow(clippy::needless_update)]
fn intersect_context() -> sys::RTCIntersectContext {
    // Re-creation of the header's inline rtcInitIntersectContext.
    sys::RTCIntersectContext {
        flags: sys::RTCIntersectContextFlags::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT,
        filter: None,
        instID: [INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
        ..Default::default()
    }
}

#[repr(C, align(32))]
struct ValidMask8([i32; PACKET_WIDTH]);

impl ValidMask8 {
    fn new(mask: LaneMask) -> Self {
        ValidMask8(std::array::from_fn(|lane| {
            if mask & (1 << lane) != 0 {
                -1
            } else {
                0
            }
        }))
    }
}

fn embree_ray(ray: &Ray) -> sys::RTCRay {
    sys::RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: ray.tmin,
        dir_x: ray.dir.x,
        dir_y: ray.dir.y,
        dir_z: ray.dir.z,
        time: 0.0,
        tfar: ray.tmax,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

fn hit_object(geom_id: u32, inst_id: u32) -> u32 {
    if inst_id != INVALID_ID {
        inst_id
    } else {
        geom_id
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

    pub fn intersect1(&self, ray: &Ray) -> Option<Hit> {
        intersect1(&[self], ray)
    }

    pub fn occluded1(&self, ray: &Ray) -> bool {
        occluded1(&[self], ray)
    }

    pub fn intersect8(&self, rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
        intersect8(&[self], rays, mask, hits)
    }

    pub fn occluded8(&self, rays: &RayPacket, mask: LaneMask) -> LaneMask {
        occluded8(&[self], rays, mask)
    }
}

// Tracing a stack of scenes: each call keeps the ray's shortened `tfar` and
// hit from the previous scene, so Embree reports the nearest hit over all of
// them. Every scene of a stack names its geometries by object id, so a hit
// says its object whichever scene it came from.

/// The lanes of `mask` worth tracing through the `index`th scene of a
/// stack: all of them for the first; for the later (small, moving) ones
/// only the lanes whose ray, as shortened so far, may cross the scene's
/// bounds. Without this every packet paid a full call into a one-sphere
/// scene: +46% instructions on the paper-bounce frame.
fn lanes_to_trace(
    scene: &CommittedScene,
    index: usize,
    ray: &sys::RTCRay8,
    mask: LaneMask,
) -> LaneMask {
    match index {
        0 => mask,
        _ if scene.bounds.is_empty() => 0,
        _ => scene.bounds.crossing_lanes_soa(
            &[ray.org_x, ray.org_y, ray.org_z],
            &[ray.dir_x, ray.dir_y, ray.dir_z],
            &ray.tnear,
            &ray.tfar,
            mask,
        ),
    }
}

fn intersect1(scenes: &[&CommittedScene], ray: &Ray) -> Option<Hit> {
    let mut rayhit = sys::RTCRayHit {
        ray: embree_ray(ray),
        hit: sys::RTCHit {
            geomID: INVALID_ID,
            primID: INVALID_ID,
            instID: [INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
            ..Default::default()
        },
    };
    for scene in scenes {
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; context and rayhit are valid for the call.
        unsafe {
            let mut context = intersect_context();
            sys::rtcIntersect1(scene.raw, &mut context, &mut rayhit);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: the scene is committed; null arguments select the defaults.
        unsafe {
            sys::rtcIntersect1(scene.raw, &mut rayhit, std::ptr::null_mut());
        }
    }
    (rayhit.hit.geomID != INVALID_ID).then(|| Hit {
        t: rayhit.ray.tfar,
        object: hit_object(rayhit.hit.geomID, rayhit.hit.instID[0]),
        prim: rayhit.hit.primID,
        u: rayhit.hit.u,
        v: rayhit.hit.v,
    })
}

fn occluded1(scenes: &[&CommittedScene], ray: &Ray) -> bool {
    let mut r = embree_ray(ray);
    for scene in scenes {
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; context and ray are valid for the call.
        unsafe {
            let mut context = intersect_context();
            sys::rtcOccluded1(scene.raw, &mut context, &mut r);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: the scene is committed; null arguments select the defaults.
        unsafe {
            sys::rtcOccluded1(scene.raw, &mut r, std::ptr::null_mut());
        }
        if r.tfar == f32::NEG_INFINITY {
            return true;
        }
    }
    false
}

fn ray8(rays: &RayPacket) -> sys::RTCRay8 {
    sys::RTCRay8 {
        org_x: rays.map(|r| r.origin.x),
        org_y: rays.map(|r| r.origin.y),
        org_z: rays.map(|r| r.origin.z),
        tnear: rays.map(|r| r.tmin),
        dir_x: rays.map(|r| r.dir.x),
        dir_y: rays.map(|r| r.dir.y),
        dir_z: rays.map(|r| r.dir.z),
        time: [0.0; PACKET_WIDTH],
        tfar: rays.map(|r| r.tmax),
        mask: [u32::MAX; PACKET_WIDTH],
        id: [0; PACKET_WIDTH],
        flags: [0; PACKET_WIDTH],
    }
}

fn intersect8(scenes: &[&CommittedScene], rays: &RayPacket, mask: LaneMask, hits: &mut HitPacket) {
    let mut rayhit = sys::RTCRayHit8 {
        ray: ray8(rays),
        hit: sys::RTCHit8 {
            geomID: [INVALID_ID; PACKET_WIDTH],
            primID: [INVALID_ID; PACKET_WIDTH],
            instID: [[INVALID_ID; PACKET_WIDTH]; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
            ..Default::default()
        },
    };
    for (index, scene) in scenes.iter().enumerate() {
        let open = lanes_to_trace(scene, index, &rayhit.ray, mask);
        if open == 0 {
            continue;
        }
        let valid = ValidMask8::new(open);
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; `valid` and `rayhit` are 32-byte
        // aligned as rtcIntersect8 requires (repr(align(32)) on both).
        unsafe {
            let mut context = intersect_context();
            sys::rtcIntersect8(valid.0.as_ptr(), scene.raw, &mut context, &mut rayhit);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: as above; null arguments select the defaults.
        unsafe {
            sys::rtcIntersect8(
                valid.0.as_ptr(),
                scene.raw,
                &mut rayhit,
                std::ptr::null_mut(),
            );
        }
    }
    for lane in lanes(mask) {
        let geom = rayhit.hit.geomID[lane];
        hits[lane] = (geom != INVALID_ID).then(|| Hit {
            t: rayhit.ray.tfar[lane],
            object: hit_object(geom, rayhit.hit.instID[0][lane]),
            prim: rayhit.hit.primID[lane],
            u: rayhit.hit.u[lane],
            v: rayhit.hit.v[lane],
        });
    }
}

fn occluded8(scenes: &[&CommittedScene], rays: &RayPacket, mask: LaneMask) -> LaneMask {
    let mut ray = ray8(rays);
    let mut occluded: LaneMask = 0;
    for (index, scene) in scenes.iter().enumerate() {
        let open = lanes_to_trace(scene, index, &ray, mask & !occluded);
        if open == 0 {
            continue;
        }
        let valid = ValidMask8::new(open);
        #[cfg(embree_version = "3")]
        // SAFETY: the scene is committed; `valid` and `ray` are 32-byte aligned.
        unsafe {
            let mut context = intersect_context();
            sys::rtcOccluded8(valid.0.as_ptr(), scene.raw, &mut context, &mut ray);
        }
        #[cfg(embree_version = "4")]
        // SAFETY: as above; null arguments select the defaults.
        unsafe {
            sys::rtcOccluded8(valid.0.as_ptr(), scene.raw, &mut ray, std::ptr::null_mut());
        }
        occluded |= lanes(open)
            .filter(|&lane| ray.tfar[lane] == f32::NEG_INFINITY)
            .fold(0, |acc, lane| acc | (1 << lane));
    }
    occluded
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
            set_transform(geometry, transform);
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
        let vertex_buffer = sys::RTCBufferType::RTC_BUFFER_TYPE_VERTEX;
        // SAFETY: as above; `id` names a sphere geometry whose vertex buffer
        // Embree allocated in `attach_sphere` with one FLOAT4 element.
        let data = unsafe {
            let geometry = sys::rtcGetGeometry(self.scene.raw, id);
            (
                geometry,
                sys::rtcGetGeometryBufferData(geometry, vertex_buffer, 0),
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
            sys::rtcUpdateGeometryBuffer(geometry, vertex_buffer, 0);
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
            // slot for the next check.
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
    Ok(())
}

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
/// scene of their own. Measured on Embree 3.13.5: a commit costs about
/// 0.2-0.5 us per triangle in the scene (2 ms beside the 3674-triangle
/// bunny; 170 ms per frame beside the 940k triangles of
/// `scenes/bunnies.toml`, where the split makes 10 frames 3.7x faster),
/// while the split costs 4.5% more instructions on the 640x480
/// paper-bounce frame (a box test per packet, and a second call for the
/// packets near the ball), about 2 ms. Small scenes stay in one scene.
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
        let moves = |object: &Object| matches!(object.placement, Placement::Instance(_));
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
                StillSplit::Auto => still_primitives >= SPLIT_MIN_STILL_PRIMITIVES,
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
                (Placement::Instance(_), Shape::Plane(_)) => {}
                (Placement::Instance(transform), Shape::Sphere(sphere)) => {
                    let placed =
                        placed_sphere(sphere, transform).ok_or_else(|| not_round(id, transform))?;
                    top.attach_sphere(id, placed.center, placed.radius)?;
                    placed_spheres.push((id, *sphere));
                }
                (Placement::Instance(transform), shape) => {
                    let mut child = SceneBuilder::new(&device)?;
                    attach_shape(&mut child, 0, shape)?;
                    top.attach_instance(id, child.commit()?, transform)?;
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
        let mut edit = self.scene.edit();
        for (object, transform) in moves {
            match self.placed_spheres.iter().find(|(id, _)| id == object) {
                Some((_, sphere)) => {
                    let placed = placed_sphere(sphere, transform)
                        .ok_or_else(|| not_round(*object, transform))?;
                    edit.move_sphere(*object, placed.center, placed.radius)?;
                }
                None => edit.set_instance_transform(*object, transform)?,
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

/// Planes are left out: [`super::Accelerator`] tests them for every backend.
fn attach_shape(scene: &mut SceneBuilder, id: u32, shape: &Shape) -> Result<(), EmbreeError> {
    match shape {
        Shape::Mesh(mesh) if !mesh.triangles.is_empty() => {
            scene.attach_triangles(id, &mesh.positions, &mesh.triangles)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_triangle_scene(device: &Device) -> CommittedScene {
        let mut builder = SceneBuilder::new(device).unwrap();
        builder
            .attach_triangles(
                3,
                &[
                    Vec3::new(-1.0, -1.0, 0.0),
                    Vec3::new(1.0, -1.0, 0.0),
                    Vec3::new(0.0, 1.0, 0.0),
                ],
                &[[0, 1, 2]],
            )
            .unwrap();
        builder
            .attach_sphere(5, Vec3::new(0.0, 0.0, -5.0), 1.0)
            .unwrap();
        builder.commit().unwrap()
    }

    #[test]
    fn device_reports_version_and_packet_support() {
        let device = Device::new().unwrap();
        assert!(device.version() >= 30000, "version {}", device.version());
        let _ = device.native_packet8();
    }

    #[test]
    fn single_ray_hits_triangle_then_sphere() {
        let device = Device::new().unwrap();
        let scene = unit_triangle_scene(&device);
        let hit = scene
            .intersect1(&Ray::new(Vec3::new(0.0, 0.0, 2.0), -Vec3::Z))
            .unwrap();
        assert_eq!((hit.object, hit.prim), (3, 0));
        assert!((hit.t - 2.0).abs() < 1e-6);
        let hit = scene.intersect1(&Ray::new(Vec3::new(0.0, 1.5, 2.0), -Vec3::Z));
        assert!(hit.is_none());
        let behind = Ray::new(Vec3::new(0.0, 0.0, -1.0), -Vec3::Z);
        let hit = scene.intersect1(&behind).unwrap();
        assert_eq!(hit.object, 5);
        assert!((hit.t - 3.0).abs() < 1e-5);
        assert!(scene.occluded1(&behind));
        assert!(!scene.occluded1(&Ray::segment(behind.origin, behind.dir, 2.5)));
    }

    #[test]
    fn packets_agree_with_single_rays_and_respect_the_mask() {
        let device = Device::new().unwrap();
        let scene = unit_triangle_scene(&device);
        let rays: RayPacket = std::array::from_fn(|i| {
            Ray::new(Vec3::new(-1.2 + 0.35 * i as f32, 0.1, 2.0), -Vec3::Z)
        });
        let mask = 0b1011_0111;
        let mut hits = [None; PACKET_WIDTH];
        scene.intersect8(&rays, mask, &mut hits);
        let occluded = scene.occluded8(&rays, mask);
        for lane in 0..PACKET_WIDTH {
            if mask & (1 << lane) == 0 {
                assert_eq!(hits[lane], None);
                assert_eq!(occluded & (1 << lane), 0);
            } else {
                assert_eq!(
                    hits[lane].map(|h| h.object),
                    scene.intersect1(&rays[lane]).map(|h| h.object)
                );
                assert_eq!(occluded & (1 << lane) != 0, scene.occluded1(&rays[lane]));
            }
        }
        assert!(hits.iter().any(Option::is_some) && hits.iter().any(Option::is_none));
    }

    #[test]
    fn instances_move_without_rebuilding_and_report_their_id() {
        let device = Device::new().unwrap();
        let mut child = SceneBuilder::new(&device).unwrap();
        child.attach_sphere(0, Vec3::ZERO, 1.0).unwrap();
        let mut top = SceneBuilder::new(&device).unwrap();
        top.attach_instance(
            7,
            child.commit().unwrap(),
            &Affine3A::from_translation(Vec3::new(0.0, 0.0, -10.0)),
        )
        .unwrap();
        let mut scene = top.commit().unwrap();
        let ray = Ray::new(Vec3::ZERO, -Vec3::Z);
        let hit = scene.intersect1(&ray).unwrap();
        assert_eq!(hit.object, 7);
        assert!((hit.t - 9.0).abs() < 1e-5);
        scene
            .set_instance_transform(7, &Affine3A::from_translation(Vec3::new(0.0, 0.0, -4.0)))
            .unwrap();
        assert!((scene.intersect1(&ray).unwrap().t - 3.0).abs() < 1e-5);
        scene
            .set_instance_transform(7, &Affine3A::from_translation(Vec3::new(5.0, 0.0, -4.0)))
            .unwrap();
        assert!(scene.intersect1(&ray).is_none());
    }

    #[test]
    fn spheres_move_in_place_and_one_edit_commits_every_move() {
        let device = Device::new().unwrap();
        let mut scene = unit_triangle_scene(&device);
        let ray = Ray::new(Vec3::new(4.0, 0.0, 2.0), -Vec3::Z);
        assert!(scene.intersect1(&ray).is_none());
        let mut edit = scene.edit();
        edit.move_sphere(5, Vec3::new(4.0, 0.0, -1.0), 0.5).unwrap();
        // Not a sphere, and not a geometry at all: refused before Embree.
        assert_eq!(
            edit.move_sphere(3, Vec3::ZERO, 1.0).unwrap_err().code,
            "invalid argument"
        );
        assert!(edit.move_sphere(42, Vec3::ZERO, 1.0).is_err());
        edit.commit().unwrap();
        let hit = scene.intersect1(&ray).unwrap();
        assert_eq!((hit.object, hit.prim), (5, 0));
        assert!((hit.t - 2.5).abs() < 1e-5, "{hit:?}");
        // Gone from where it was.
        let old = Ray::new(Vec3::new(0.0, 0.0, -1.0), -Vec3::Z);
        assert!(scene.intersect1(&old).is_none() && !scene.occluded1(&old));
        // An edit dropped early (as by `?`) still commits what it moved.
        {
            let mut edit = scene.edit();
            edit.move_sphere(5, Vec3::new(4.0, 0.0, -3.0), 0.5).unwrap();
        }
        assert!((scene.intersect1(&ray).unwrap().t - 4.5).abs() < 1e-5);
    }

    /// The bindings come from the Embree 4 headers, so the library must be
    /// the same 4.x minor release: struct layouts change between them (4.3
    /// added `instPrimID` to hits), and a mismatch corrupts rays silently.
    #[cfg(embree_version = "4")]
    #[test]
    fn embree4_library_matches_its_headers() {
        let device = Device::new().unwrap();
        assert_eq!(
            device.version() / 100,
            i64::from(sys::RTC_VERSION / 100),
            "library {} vs headers {}",
            device.version(),
            sys::RTC_VERSION
        );
    }

    #[test]
    fn embree_errors_become_results() {
        let device = Device::new().unwrap();
        let builder = SceneBuilder::new(&device).unwrap();
        // A geometry type Embree does not know: reported through the callback.
        let err = builder
            .new_geometry(sys::RTCGeometryType(9999))
            .unwrap_err();
        assert!(err.message.contains("geometry type"), "{err}");
        // The slot was cleared: later calls succeed again.
        assert!(device.take_error().is_ok());
        let mut scene = unit_triangle_scene(&device);
        let err = scene
            .set_instance_transform(42, &Affine3A::IDENTITY)
            .unwrap_err();
        assert_eq!(err.code, "invalid argument");
    }
}
