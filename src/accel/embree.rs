//! The Embree backend: Debian's Embree (3, or 4 where installed) through bindings that
//! `build.rs` generates from the installed headers. This is the only module with `unsafe` in
//! the project; every block says why it is sound.
//!
//! Choices:
//! - Scene flag `ROBUST` and build quality `HIGH`: renders query the same scene billions of
//!   times, so a slower, better tree pays for itself; robust mode keeps traversal watertight
//!   and free of false misses at shared edges (the watertightness test counts them).
//! - The vertex buffer is the scene's own triangle array (three `Vec3A`, 16 bytes apart),
//!   shared without a copy; only the trivial index buffer `3i, 3i+1, 3i+2` is allocated.
//! - Packets: `rtcIntersect8`/`rtcOccluded8` back the batched trait methods.
#![allow(unsafe_code)]

use super::Accel;
use crate::geometry::{Hit, Ray};
use crate::{Error, Result};
use glam::Vec3A;
use std::ffi::{CStr, c_void};
use std::marker::PhantomData;
use std::ptr::{NonNull, null};
use std::sync::Mutex;

#[allow(non_upper_case_globals, non_camel_case_types, non_snake_case, dead_code, unsafe_op_in_unsafe_fn)]
#[allow(clippy::all)]
mod sys {
    include!(concat!(env!("OUT_DIR"), "/embree_bindings.rs"));
}

/// `RTC_INVALID_GEOMETRY_ID` (a macro bindgen does not emit).
const INVALID_ID: u32 = u32::MAX;

/// The lane mask of an 8-wide packet call: Embree reads it with aligned vector loads, so it
/// must be aligned like the packet (32 bytes); a plain `[i32; 8]` is only 4-byte aligned and
/// crashes whenever the stack happens to place it off a 32-byte boundary.
#[repr(C, align(32))]
struct ValidMask8([i32; 8]);

/// The first error Embree reported through its callback, kept until we read it.
struct ErrorSlot(Mutex<Option<String>>);

/// Embree calls this on any error; it must not unwind, so it only records the message.
///
/// # Safety
/// Only Embree calls it, with `user` the `ErrorSlot` registered with the device and `message`
/// null or a NUL-terminated string valid for the call.
unsafe extern "C" fn record_error(user: *mut c_void, code: sys::RTCError, message: *const std::os::raw::c_char) {
    // SAFETY: `user` is the `ErrorSlot` registered with the device, which outlives the device
    // (it is dropped after `rtcReleaseDevice`); `message` is null or a NUL-terminated string
    // valid for this call, per Embree's documentation.
    let (slot, text) = unsafe {
        let text =
            if message.is_null() { String::new() } else { CStr::from_ptr(message).to_string_lossy().into_owned() };
        (&*(user as *const ErrorSlot), text)
    };
    if let Ok(mut first) = slot.0.lock()
        && first.is_none()
    {
        *first = Some(format!("Embree error {code}: {text}"));
    }
}

/// An Embree device, released on drop.
struct Device {
    raw: sys::RTCDevice,
    errors: Box<ErrorSlot>,
}

impl Device {
    fn new() -> Result<Self> {
        // SAFETY: a null config string asks for the default device; the call has no other
        // preconditions.
        let raw = unsafe { sys::rtcNewDevice(null()) };
        if raw.is_null() {
            // SAFETY: rtcGetDeviceError accepts a null device and reports the creation error.
            let code = unsafe { sys::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(Error::Backend(format!("cannot create an Embree device (error {code})")));
        }
        let errors = Box::new(ErrorSlot(Mutex::new(None)));
        // SAFETY: `raw` is a live device; the user pointer is the boxed slot, whose address is
        // stable and which this struct drops only after releasing the device.
        unsafe { sys::rtcSetDeviceErrorFunction(raw, Some(record_error), &*errors as *const ErrorSlot as *mut c_void) };
        Ok(Self { raw, errors })
    }

    /// Turns a recorded Embree error into ours.
    fn check(&self, what: &str) -> Result<()> {
        match self.errors.0.lock().ok().and_then(|mut e| e.take()) {
            Some(message) => Err(Error::Backend(format!("{what}: {message}"))),
            None => Ok(()),
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: `raw` is a live device owned by this struct; it is released exactly once.
        unsafe { sys::rtcReleaseDevice(self.raw) };
    }
}

/// An Embree scene over a scene's triangles (`Scene::triangles`), which it borrows: the vertex
/// buffer is shared, not copied, so the triangles must outlive it.
pub struct EmbreeAccel<'s> {
    raw: NonNull<sys::RTCSceneTy>,
    /// Kept alive for the geometry, which reads it.
    _indices: Vec<[u32; 3]>,
    /// Owns the device; dropped (released) after the scene, as fields drop after `drop()`.
    _device: Device,
    _triangles: PhantomData<&'s [[Vec3A; 3]]>,
}

// SAFETY: Embree scenes are safe to query from many threads at once after `rtcCommitScene`;
// nothing here is mutated after construction.
unsafe impl Sync for EmbreeAccel<'_> {}
// SAFETY: the handles can move between threads; Embree has no thread affinity.
unsafe impl Send for EmbreeAccel<'_> {}

impl<'s> EmbreeAccel<'s> {
    pub fn build(triangles: &'s [[Vec3A; 3]]) -> Result<Self> {
        let device = Device::new()?;
        let n = triangles.len();
        let indices: Vec<[u32; 3]> = (0..n as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        // SAFETY: `device.raw` is live. The shared vertex buffer points into
        // `triangles`, which is borrowed for 's (longer than this accel) and laid out as
        // 3·n `Vec3A` (x, y, z, pad) 16 bytes apart, so FLOAT3 with stride 16 reads each vertex
        // and Embree's 16-byte over-read of the last one stays inside the allocation. The index
        // buffer is owned by the returned struct, which releases the scene before dropping it.
        let raw = unsafe {
            let raw = sys::rtcNewScene(device.raw);
            sys::rtcSetSceneFlags(raw, sys::RTCSceneFlags_RTC_SCENE_FLAG_ROBUST);
            sys::rtcSetSceneBuildQuality(raw, sys::RTCBuildQuality_RTC_BUILD_QUALITY_HIGH);
            let geometry = sys::rtcNewGeometry(device.raw, sys::RTCGeometryType_RTC_GEOMETRY_TYPE_TRIANGLE);
            sys::rtcSetSharedGeometryBuffer(
                geometry,
                sys::RTCBufferType_RTC_BUFFER_TYPE_VERTEX,
                0,
                sys::RTCFormat_RTC_FORMAT_FLOAT3,
                triangles.as_ptr() as *const c_void,
                0,
                16,
                3 * n,
            );
            sys::rtcSetSharedGeometryBuffer(
                geometry,
                sys::RTCBufferType_RTC_BUFFER_TYPE_INDEX,
                0,
                sys::RTCFormat_RTC_FORMAT_UINT3,
                indices.as_ptr() as *const c_void,
                0,
                12,
                n,
            );
            sys::rtcCommitGeometry(geometry);
            sys::rtcAttachGeometry(raw, geometry);
            sys::rtcReleaseGeometry(geometry);
            sys::rtcCommitScene(raw);
            raw
        };
        device.check("building the Embree scene")?;
        let raw = NonNull::new(raw).ok_or_else(|| Error::Backend("Embree returned no scene".into()))?;
        Ok(Self { raw, _indices: indices, _device: device, _triangles: PhantomData })
    }
}

impl Drop for EmbreeAccel<'_> {
    fn drop(&mut self) {
        // SAFETY: `raw` is a live scene owned by this struct, released once, before the device
        // (fields drop after this body) and before the index buffer it reads.
        unsafe { sys::rtcReleaseScene(self.raw.as_ptr()) };
    }
}

/// Embree 3 takes an intersect context (its initialiser is force-inlined in the header, so it
/// is written here); Embree 4 takes optional arguments instead. The only version difference.
#[cfg(not(embree4))]
mod query {
    use super::sys;

    #[inline(always)]
    // Needed where Embree is built with several instance levels (an extra field).
    #[allow(clippy::needless_update)]
    pub fn context() -> sys::RTCIntersectContext {
        // `instStackSize` exists only in multi-level builds; the default zeroes it.
        sys::RTCIntersectContext {
            flags: sys::RTCIntersectContextFlags_RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT,
            filter: None,
            instID: [super::INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
            ..Default::default()
        }
    }

    macro_rules! call {
        ($f:ident, $scene:expr, $ray:expr) => {{
            let mut ctx = query::context();
            sys::$f($scene, &mut ctx, $ray)
        }};
        ($f:ident, $valid:expr, $scene:expr, $ray:expr) => {{
            let mut ctx = query::context();
            sys::$f($valid, $scene, &mut ctx, $ray)
        }};
    }
    pub(super) use call;
}

#[cfg(embree4)]
mod query {
    macro_rules! call {
        ($f:ident, $scene:expr, $ray:expr) => {{ super::sys::$f($scene, $ray, std::ptr::null_mut()) }};
        ($f:ident, $valid:expr, $scene:expr, $ray:expr) => {{ super::sys::$f($valid, $scene, $ray, std::ptr::null_mut()) }};
    }
    pub(super) use call;
}
use query::call;

#[inline(always)]
fn ray1(ray: &Ray, t_max: f32) -> sys::RTCRay {
    sys::RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: 0.0,
        dir_x: ray.dir.x,
        dir_y: ray.dir.y,
        dir_z: ray.dir.z,
        time: 0.0,
        tfar: t_max,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

#[inline(always)]
fn empty_hit() -> sys::RTCHit {
    sys::RTCHit {
        geomID: INVALID_ID,
        primID: INVALID_ID,
        instID: [INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
        ..Default::default()
    }
}

impl Accel for EmbreeAccel<'_> {
    fn name(&self) -> &'static str {
        "embree"
    }

    #[inline]
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if !ray.is_valid() {
            return None;
        }
        let mut rh = sys::RTCRayHit { ray: ray1(ray, f32::INFINITY), hit: empty_hit() };
        // SAFETY: the scene is committed and live; `rh` is a properly initialised, suitably
        // aligned RTCRayHit that Embree may write for the duration of the call.
        unsafe { call!(rtcIntersect1, self.raw.as_ptr(), &mut rh) };
        (rh.hit.geomID != INVALID_ID).then_some(Hit { t: rh.ray.tfar, prim: rh.hit.primID, u: rh.hit.u, v: rh.hit.v })
    }

    #[inline]
    fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        if !ray.is_valid() || t_max.is_nan() || t_max <= 0.0 {
            return false;
        }
        let mut r = ray1(ray, t_max);
        // SAFETY: as in `intersect`; Embree sets `tfar` to -inf when something is hit.
        unsafe { call!(rtcOccluded1, self.raw.as_ptr(), &mut r) };
        r.tfar == f32::NEG_INFINITY
    }

    fn intersect_batch(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (rays, hits) in rays.chunks(8).zip(hits.chunks_mut(8)) {
            let mut packet = sys::RTCRayHit8::default();
            let mut valid = ValidMask8([0; 8]);
            for (i, r) in rays.iter().enumerate() {
                if !r.is_valid() {
                    continue;
                }
                valid.0[i] = -1;
                let (p, h) = (&mut packet.ray, &mut packet.hit);
                (p.org_x[i], p.org_y[i], p.org_z[i]) = (r.origin.x, r.origin.y, r.origin.z);
                (p.dir_x[i], p.dir_y[i], p.dir_z[i]) = (r.dir.x, r.dir.y, r.dir.z);
                (p.tnear[i], p.tfar[i], p.mask[i]) = (0.0, f32::INFINITY, u32::MAX);
                h.geomID[i] = INVALID_ID;
            }
            // SAFETY: `packet` is a 32-byte aligned RTCRayHit8 (bindgen keeps the header's
            // alignment) and `valid` a 32-byte aligned mask, as Embree's packet calls require;
            // every lane `valid` marks is initialised; invalid lanes are ignored.
            unsafe { call!(rtcIntersect8, valid.0.as_ptr(), self.raw.as_ptr(), &mut packet) };
            for (i, h) in hits.iter_mut().enumerate() {
                *h = (valid.0[i] != 0 && packet.hit.geomID[i] != INVALID_ID).then(|| Hit {
                    t: packet.ray.tfar[i],
                    prim: packet.hit.primID[i],
                    u: packet.hit.u[i],
                    v: packet.hit.v[i],
                });
            }
        }
    }

    fn occluded_batch(&self, rays: &[Ray], t_max: &[f32], out: &mut [bool]) {
        for ((rays, t_max), out) in rays.chunks(8).zip(t_max.chunks(8)).zip(out.chunks_mut(8)) {
            let mut packet = sys::RTCRay8::default();
            let mut valid = ValidMask8([0; 8]);
            for (i, (r, &t)) in rays.iter().zip(t_max).enumerate() {
                if !r.is_valid() || t.is_nan() || t <= 0.0 {
                    continue;
                }
                valid.0[i] = -1;
                (packet.org_x[i], packet.org_y[i], packet.org_z[i]) = (r.origin.x, r.origin.y, r.origin.z);
                (packet.dir_x[i], packet.dir_y[i], packet.dir_z[i]) = (r.dir.x, r.dir.y, r.dir.z);
                (packet.tnear[i], packet.tfar[i], packet.mask[i]) = (0.0, t, u32::MAX);
            }
            // SAFETY: as in `intersect_batch`, with an aligned RTCRay8 and mask.
            unsafe { call!(rtcOccluded8, valid.0.as_ptr(), self.raw.as_ptr(), &mut packet) };
            for (i, o) in out.iter_mut().enumerate() {
                *o = valid.0[i] != 0 && packet.tfar[i] == f32::NEG_INFINITY;
            }
        }
    }
}
