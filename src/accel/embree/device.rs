//! The Embree device, and the funnel through which Embree's errors reach
//! Rust: Embree's error callback records them in the device's error slot,
//! and [`Device::take_error`] turns the slot into a `Result`.
//!
//! Promises:
//! - The error slot lives as long as the device: it is boxed beside the
//!   device handle and freed only after `rtcReleaseDevice`, so the callback
//!   never sees a dangling slot.
//! - The slot keeps the first error since it was last read, and reading it
//!   clears it. It is read after building calls, never per ray.
//! - A panic in the error callback never unwinds into Embree: it is caught
//!   there and raised again by the wrapper that made the call, once Embree
//!   has returned; [`Device::take_error`] raises it before it reads the
//!   slot (see `callback_panic.rs`).
//! - A device is cheap to clone and shared: every scene holds a clone, so
//!   the device outlives its scenes.

use std::ffi::{c_char, c_void, CStr};
use std::sync::Mutex;

use super::{callback_panic, sys};

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
    /// Makes the callback panic once, for the test that a panic there
    /// reaches the caller.
    #[cfg(test)]
    panic_on_next_error: std::sync::atomic::AtomicBool,
}

/// Embree's error callback: the one Rust function Embree calls.
///
/// # Safety
/// Only Embree calls it, as registered in [`Device::new`]: `user` is that
/// device's `ErrorSlot`, and `text` is null or a NUL-terminated string that
/// lives for the call.
unsafe extern "C" fn record_error(user: *mut c_void, code: sys::RTCError, text: *const c_char) {
    // A panic must not unwind into C: it is caught here and raised again by
    // the wrapper that called Embree, once Embree has returned.
    callback_panic::catch(|| {
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
        #[cfg(test)]
        if slot
            .panic_on_next_error
            .swap(false, std::sync::atomic::Ordering::Relaxed)
        {
            panic!("panic in the error callback on: {message}");
        }
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
            #[cfg(test)]
            panic_on_next_error: Default::default(),
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
        let device = Device {
            inner: std::sync::Arc::new(DeviceInner { raw, errors }),
        };
        callback_panic::resume();
        Ok(device)
    }

    /// The raw handle, for the wrappers that create scenes and geometries
    /// on this device.
    pub(super) fn raw(&self) -> sys::RTCDevice {
        self.inner.raw
    }

    /// Returns (and clears) the first error Embree reported since the last
    /// call. Raises first any panic the error callback caught on this thread.
    pub(super) fn take_error(&self) -> Result<(), EmbreeError> {
        callback_panic::resume();
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
        let version = unsafe {
            sys::rtcGetDeviceProperty(
                self.inner.raw,
                sys::RTCDeviceProperty::RTC_DEVICE_PROPERTY_VERSION,
            ) as i64
        };
        callback_panic::resume();
        version
    }

    pub fn native_packet8(&self) -> bool {
        // SAFETY: querying a property of a live device.
        let native = unsafe {
            sys::rtcGetDeviceProperty(
                self.inner.raw,
                sys::RTCDeviceProperty::RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED,
            ) != 0
        };
        callback_panic::resume();
        native
    }

    /// Makes the error callback panic at the next error it records.
    #[cfg(test)]
    pub(super) fn panic_on_next_error(&self) {
        self.inner
            .errors
            .panic_on_next_error
            .store(true, std::sync::atomic::Ordering::Relaxed);
    }
}
