//! The Intel Open Image Denoise 2.x C API, loaded at run time: the one place outside the
//! Embree bindings where `unsafe` code lives. Every call goes through [`Oidn`], whose safe
//! methods keep the invariants the C API needs (live handles, buffers that outlive the
//! filter's execution, names as NUL-terminated strings).
#![allow(unsafe_code)]
use std::ffi::{CStr, CString, c_char, c_int, c_void};
use std::path::{Path, PathBuf};

type Device = *mut c_void;
type Filter = *mut c_void;

/// `OIDN_DEVICE_TYPE_CPU`.
const DEVICE_CPU: c_int = 1;
/// `OIDN_FORMAT_FLOAT3`.
const FORMAT_FLOAT3: c_int = 3;
/// `OIDN_ERROR_NONE`.
const ERROR_NONE: c_int = 0;

/// The entry points zvidpt uses, resolved from the library.
struct Api {
    new_device: unsafe extern "C" fn(c_int) -> Device,
    commit_device: unsafe extern "C" fn(Device),
    release_device: unsafe extern "C" fn(Device),
    device_error: unsafe extern "C" fn(Device, *mut *const c_char) -> c_int,
    set_device_int: unsafe extern "C" fn(Device, *const c_char, c_int),
    new_filter: unsafe extern "C" fn(Device, *const c_char) -> Filter,
    set_shared_image:
        unsafe extern "C" fn(Filter, *const c_char, *mut c_void, c_int, usize, usize, usize, usize, usize),
    set_filter_bool: unsafe extern "C" fn(Filter, *const c_char, bool),
    commit_filter: unsafe extern "C" fn(Filter),
    execute_filter: unsafe extern "C" fn(Filter),
    release_filter: unsafe extern "C" fn(Filter),
}

/// A loaded Open Image Denoise and one committed CPU device.
pub struct Oidn {
    api: Api,
    device: Device,
    /// Where it was loaded from.
    pub path: PathBuf,
    // Keeps the library mapped while `api`'s pointers are in use (dropped last).
    _library: libloading::Library,
}

/// One image bound to a filter: its name and 3-float pixels (read, or written by the filter).
pub enum Image<'a> {
    /// An input the filter reads.
    Input(&'static CStr, &'a [[f32; 3]]),
    /// The output the filter writes.
    Output(&'static CStr, &'a mut [[f32; 3]]),
}

impl Oidn {
    /// Loads the library at `path` and opens a CPU device on `threads` threads (0: all).
    pub fn load(path: &Path, threads: usize) -> Result<Self, String> {
        // SAFETY: loading a shared library runs its initialisers; Open Image Denoise's are
        // ordinary C++ static constructors with no preconditions on the caller.
        let library = unsafe { libloading::Library::new(path) }.map_err(|e| e.to_string())?;
        macro_rules! symbol {
            ($name:literal) => {
                // SAFETY: the symbol's type is the C declaration of this name in
                // OpenImageDenoise/oidn.h (2.x), copied into `Api`'s field types; the
                // pointer is used only while `library` is loaded (it is kept in `Oidn`).
                *unsafe { library.get(concat!($name, "\0").as_bytes()) }
                    .map_err(|e| format!("{}: no `{}`: {e}", path.display(), $name))?
            };
        }
        let api = Api {
            new_device: symbol!("oidnNewDevice"),
            commit_device: symbol!("oidnCommitDevice"),
            release_device: symbol!("oidnReleaseDevice"),
            device_error: symbol!("oidnGetDeviceError"),
            set_device_int: symbol!("oidnSetDeviceInt"),
            new_filter: symbol!("oidnNewFilter"),
            set_shared_image: symbol!("oidnSetSharedFilterImage"),
            set_filter_bool: symbol!("oidnSetFilterBool"),
            commit_filter: symbol!("oidnCommitFilter"),
            execute_filter: symbol!("oidnExecuteFilter"),
            release_filter: symbol!("oidnReleaseFilter"),
        };
        // SAFETY: `oidnNewDevice` takes a device type by value and returns a handle or null.
        let device = unsafe { (api.new_device)(DEVICE_CPU) };
        if device.is_null() {
            return Err("cannot create a CPU device (is the CPU device library beside it?)".into());
        }
        let oidn = Self { api, device, path: path.to_path_buf(), _library: library };
        let threads = c_int::try_from(threads).unwrap_or(0);
        // SAFETY: `device` is a live handle, not yet committed; the name is NUL-terminated.
        unsafe { (oidn.api.set_device_int)(oidn.device, c"numThreads".as_ptr(), threads) };
        // SAFETY: `device` is a live handle.
        unsafe { (oidn.api.commit_device)(oidn.device) };
        oidn.check("opening the CPU device")?;
        Ok(oidn)
    }

    /// The device's pending error, if any, as one line.
    fn check(&self, doing: &str) -> Result<(), String> {
        let mut message: *const c_char = std::ptr::null();
        // SAFETY: `device` is live; the function writes a pointer to a string the device
        // owns until its next call, which is copied before returning.
        let code = unsafe { (self.api.device_error)(self.device, &raw mut message) };
        if code == ERROR_NONE {
            return Ok(());
        }
        let text = if message.is_null() {
            String::new()
        } else {
            // SAFETY: non-null, NUL-terminated, owned by the device and unchanged until the
            // next API call on it (none happens before this copy).
            unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned()
        };
        Err(format!("{doing}: Open Image Denoise error {code}: {text}"))
    }

    /// Runs a filter of `kind` (e.g. `RT`) over `width × height` images, with the boolean
    /// parameters `flags` set, writing its output image.
    pub fn run(
        &self,
        kind: &str,
        width: usize,
        height: usize,
        images: &mut [Image<'_>],
        flags: &[(&'static CStr, bool)],
    ) -> Result<(), String> {
        let pixels = width.checked_mul(height).ok_or("image too large")?;
        let kind = CString::new(kind).map_err(|e| e.to_string())?;
        // SAFETY: `device` is live and committed; `kind` is NUL-terminated.
        let filter = unsafe { (self.api.new_filter)(self.device, kind.as_ptr()) };
        if filter.is_null() {
            self.check("creating the filter")?;
            return Err("cannot create the filter".into());
        }
        // Released however this ends.
        struct Release<'a>(&'a Api, Filter);
        impl Drop for Release<'_> {
            fn drop(&mut self) {
                // SAFETY: the filter is live and released once, here.
                unsafe { (self.0.release_filter)(self.1) };
            }
        }
        let _release = Release(&self.api, filter);
        let stride = std::mem::size_of::<[f32; 3]>();
        for image in images.iter_mut() {
            let (name, ptr, len) = match image {
                Image::Input(name, p) => (*name, p.as_ptr().cast_mut().cast::<c_void>(), p.len()),
                Image::Output(name, p) => (*name, p.as_mut_ptr().cast::<c_void>(), p.len()),
            };
            if len != pixels {
                return Err(format!("`{}` holds {len} pixels, not {pixels}", name.to_string_lossy()));
            }
            // SAFETY: `filter` is live; `ptr` points to `pixels` packed 3-float pixels that
            // stay borrowed (so alive, and unaliased for the output) until this function
            // returns, after the filter's synchronous execution and release. Inputs are only
            // read by the filter.
            unsafe {
                (self.api.set_shared_image)(
                    filter,
                    name.as_ptr(),
                    ptr,
                    FORMAT_FLOAT3,
                    width,
                    height,
                    0,
                    stride,
                    stride * width,
                )
            };
        }
        for (name, value) in flags {
            // SAFETY: `filter` is live; the name is NUL-terminated.
            unsafe { (self.api.set_filter_bool)(filter, name.as_ptr(), *value) };
        }
        // SAFETY: `filter` is live, with its images set.
        unsafe { (self.api.commit_filter)(filter) };
        self.check("setting up the filter")?;
        // SAFETY: committed; executes synchronously on the CPU device, reading and writing
        // only the images bound above, which are all alive.
        unsafe { (self.api.execute_filter)(filter) };
        self.check("denoising")
    }
}

impl Drop for Oidn {
    fn drop(&mut self) {
        // SAFETY: the device is live, every filter made from it has been released, and it is
        // released once, here (before the library is unloaded: fields drop after this).
        unsafe { (self.api.release_device)(self.device) };
    }
}
