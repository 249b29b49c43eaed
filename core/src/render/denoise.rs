//! Denoising of beauty frames with Intel Open Image Denoise 2 (OIDN), loaded at run time.
//!
//! The library is not linked: `prismbake` runs without it, and `--denoise` loads it from, in
//! order, `PRISMBAKE_OIDN` (the library file or the folder that holds it; when it is set,
//! nothing else is tried), the folder `install.sh` puts it in (`$XDG_DATA_HOME/prismbake/oidn/lib`,
//! else `~/.local/share/prismbake/oidn/lib`), then the system loader's path. Blender ships the
//! same library in its `lib` folder; the add-on points `PRISMBAKE_OIDN` there.
//!
//! What is filtered is the asset's radiance (premultiplied by its coverage, as the EXR holds
//! it), guided by the first hit's albedo and shading normal averaged over each pixel's samples
//! (`BeautyImage::features`): the normals carry the relief, so the filter keeps it. The
//! background and the catcher's shadow (in alpha) are left as they are; pixels the asset does
//! not cover stay empty. The filter runs on the CPU device: the frame is in host memory
//! (docs/denoising.md: what is filtered, the library's places, quality, time and error).

use super::beauty::BeautyImage;
use crate::error::{Error, Result};
use libloading::Library;
use std::ffi::{c_char, c_void, CStr};
use std::mem::ManuallyDrop;
use std::path::{Path, PathBuf};

/// The environment variable naming the library (a file, or a folder holding it).
pub const ENV_VAR: &str = "PRISMBAKE_OIDN";

#[cfg(target_os = "linux")]
const LIB_NAME: &str = "libOpenImageDenoise.so.2";
#[cfg(target_os = "macos")]
const LIB_NAME: &str = "libOpenImageDenoise.2.dylib";
#[cfg(target_os = "windows")]
const LIB_NAME: &str = "OpenImageDenoise.dll";

// The C API's enums (oidn.h): OIDN_DEVICE_TYPE_CPU, OIDN_FORMAT_FLOAT3.
const DEVICE_TYPE_CPU: i32 = 1;
const FORMAT_FLOAT3: i32 = 3;
/// OIDN 2.0.0 as `oidnGetDeviceInt(device, "version")` reports it (major·10000 + minor·100 + patch).
const MIN_VERSION: i32 = 20000;

/// The filter's quality (OIDN's `quality`): its network's size. A 512² frame on 2 CPU cores
/// (AMD EPYC Zen 1, OIDN 2.5.1) takes 2.5 s at `High`, 1.0 s at `Balanced` and 0.52 s at
/// `Fast`, whatever the samples per pixel (docs/denoising.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Quality {
    /// Final frames (OIDN's default).
    #[default]
    High,
    /// Previews and turntables: about 2.5× faster.
    Balanced,
    /// Interactive previews: about 5× faster (OIDN 2.3 or later).
    Fast,
}

impl Quality {
    /// OIDN_QUALITY_HIGH, _BALANCED, _FAST.
    fn oidn(self) -> i32 {
        match self {
            Quality::High => 6,
            Quality::Balanced => 5,
            Quality::Fast => 4,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Quality::High => "high",
            Quality::Balanced => "balanced",
            Quality::Fast => "fast",
        }
    }
}

type DevicePtr = *mut c_void;
type FilterPtr = *mut c_void;

/// The entry points used, resolved once from the loaded library.
struct Api {
    new_device: unsafe extern "C" fn(i32) -> DevicePtr,
    commit_device: unsafe extern "C" fn(DevicePtr),
    release_device: unsafe extern "C" fn(DevicePtr),
    get_device_error: unsafe extern "C" fn(DevicePtr, *mut *const c_char) -> i32,
    get_device_int: unsafe extern "C" fn(DevicePtr, *const c_char) -> i32,
    set_device_int: unsafe extern "C" fn(DevicePtr, *const c_char, i32),
    new_filter: unsafe extern "C" fn(DevicePtr, *const c_char) -> FilterPtr,
    release_filter: unsafe extern "C" fn(FilterPtr),
    #[allow(clippy::type_complexity)]
    set_shared_filter_image: unsafe extern "C" fn(
        FilterPtr,
        *const c_char,
        *mut c_void,
        i32,
        usize,
        usize,
        usize,
        usize,
        usize,
    ),
    set_filter_bool: unsafe extern "C" fn(FilterPtr, *const c_char, bool),
    set_filter_int: unsafe extern "C" fn(FilterPtr, *const c_char, i32),
    commit_filter: unsafe extern "C" fn(FilterPtr),
    execute_filter: unsafe extern "C" fn(FilterPtr),
}

impl Api {
    /// # Safety
    /// `lib` must be Open Image Denoise 2 (the symbols' C signatures are those of oidn.h), and
    /// the pointers are valid only while `lib` stays loaded.
    unsafe fn resolve(lib: &Library) -> std::result::Result<Api, String> {
        macro_rules! sym {
            ($name:literal) => {
                *lib.get(concat!($name, "\0").as_bytes())
                    .map_err(|e| format!("no {} ({e}): not Open Image Denoise 2", $name))?
            };
        }
        Ok(Api {
            new_device: sym!("oidnNewDevice"),
            commit_device: sym!("oidnCommitDevice"),
            release_device: sym!("oidnReleaseDevice"),
            get_device_error: sym!("oidnGetDeviceError"),
            get_device_int: sym!("oidnGetDeviceInt"),
            set_device_int: sym!("oidnSetDeviceInt"),
            new_filter: sym!("oidnNewFilter"),
            release_filter: sym!("oidnReleaseFilter"),
            set_shared_filter_image: sym!("oidnSetSharedFilterImage"),
            set_filter_bool: sym!("oidnSetFilterBool"),
            set_filter_int: sym!("oidnSetFilterInt"),
            commit_filter: sym!("oidnCommitFilter"),
            execute_filter: sym!("oidnExecuteFilter"),
        })
    }
}

/// A loaded Open Image Denoise, its CPU device and the quality its filters run at.
pub struct Denoiser {
    api: Api,
    device: DevicePtr,
    path: PathBuf,
    version: i32,
    quality: Quality,
    // Never unloaded: `api`'s pointers point into it, and the TBB it brings may keep worker
    // threads and thread-exit handlers alive after the device is released (loading it again,
    // as `render DIR` does per asset, only takes another reference).
    _lib: ManuallyDrop<Library>,
}

// SAFETY: OIDN's API is thread-safe (calls on one device are serialised by the library), the
// device handle is only passed to it, and errors are read on the thread of the failing call.
unsafe impl Send for Denoiser {}
unsafe impl Sync for Denoiser {}

impl Drop for Denoiser {
    fn drop(&mut self) {
        // SAFETY: the device was created by this library and is released once.
        unsafe { (self.api.release_device)(self.device) }
    }
}

impl std::fmt::Debug for Denoiser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.describe())
    }
}

/// Where the library is looked for, in order (see the module's documentation).
fn candidates() -> Vec<PathBuf> {
    if let Some(v) = std::env::var_os(ENV_VAR).filter(|v| !v.is_empty()) {
        let p = PathBuf::from(v);
        return vec![if p.is_dir() { p.join(LIB_NAME) } else { p }];
    }
    let mut out = vec![];
    let data = std::env::var_os("XDG_DATA_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".local/share")));
    if let Some(d) = data {
        let p = d.join("prismbake/oidn/lib").join(LIB_NAME);
        if p.exists() {
            out.push(p);
        }
    }
    // A bare name: the system loader's search (LD_LIBRARY_PATH, the system's folders).
    out.push(PathBuf::from(LIB_NAME));
    out
}

impl Denoiser {
    /// Load the library and create its CPU device, to filter at `quality`; the error lists
    /// every place tried and says how to get the library.
    pub fn load(quality: Quality) -> Result<Denoiser> {
        let mut tried = vec![];
        for path in candidates() {
            match Self::load_from(&path, quality) {
                Ok(d) => return Ok(d),
                Err(why) => tried.push(format!("{}: {why}", path.display())),
            }
        }
        Err(Error::Param(format!(
            "--denoise: Open Image Denoise 2 could not be loaded ({}). Run ./install.sh, which \
             puts it in ~/.local/share/prismbake/oidn/lib; or install it system-wide; or set {ENV_VAR} \
             to a {LIB_NAME} (Blender ships one in its lib folder). Leave out --denoise to render \
             without it",
            tried.join("; ")
        )))
    }

    fn load_from(path: &Path, quality: Quality) -> std::result::Result<Denoiser, String> {
        // SAFETY: loading runs the library's initialisers; OIDN's only set up its own state.
        let lib = unsafe { Library::new(path) }.map_err(|e| e.to_string())?;
        // SAFETY: the symbols are checked to exist; their signatures are OIDN 2's.
        let api = unsafe { Api::resolve(&lib) }?;
        // SAFETY: plain calls into the library; a null device is checked before any use.
        unsafe {
            let device = (api.new_device)(DEVICE_TYPE_CPU);
            if device.is_null() {
                return Err(format!(
                    "no CPU device: {}",
                    error_message(&api, std::ptr::null_mut())
                        .unwrap_or_else(|| "no reason given".into())
                ));
            }
            // As many threads as the job renders with (`--threads`; rayon's pool when the
            // job opens), not every core of the machine.
            let threads = rayon::current_num_threads().min(i32::MAX as usize) as i32;
            (api.set_device_int)(device, c"numThreads".as_ptr(), threads);
            (api.commit_device)(device);
            let version = (api.get_device_int)(device, c"version".as_ptr());
            let d = Denoiser {
                api,
                device,
                path: path.to_path_buf(),
                version,
                quality,
                _lib: ManuallyDrop::new(lib),
            };
            if let Some(e) = error_message(&d.api, device) {
                return Err(format!("its CPU device failed: {e}"));
            }
            if version < MIN_VERSION {
                return Err(format!(
                    "version {} is too old (2.0 or later is needed)",
                    version_string(version)
                ));
            }
            Ok(d)
        }
    }

    /// "Open Image Denoise 2.3.3, high quality (PATH)", for logs and summaries.
    pub fn describe(&self) -> String {
        format!(
            "Open Image Denoise {}, {} quality ({})",
            version_string(self.version),
            self.quality.name(),
            self.path.display()
        )
    }

    /// Filter `color` (linear RGB, row-major `width × height`, in OIDN's HDR mode) in place
    /// with the `RT` filter at the denoiser's quality, guided by `albedo` and `normal` (both
    /// noise-free: `cleanAux`).
    pub fn filter(
        &self,
        width: u32,
        height: u32,
        color: &mut [[f32; 3]],
        albedo: &[[f32; 3]],
        normal: &[[f32; 3]],
    ) -> std::result::Result<(), String> {
        let n = width as usize * height as usize;
        if color.len() != n || albedo.len() != n || normal.len() != n {
            return Err(format!(
                "image sizes differ from {width}x{height}: colour {}, albedo {}, normal {}",
                color.len(),
                albedo.len(),
                normal.len()
            ));
        }
        if n == 0 {
            return Ok(());
        }
        let mut output = vec![[0.0f32; 3]; n];
        let a = &self.api;
        // SAFETY: every image is `n` packed float triples that outlive the filter's execution
        // (the filter is released before returning); the inputs are only read.
        unsafe {
            let filter = (a.new_filter)(self.device, c"RT".as_ptr());
            if filter.is_null() {
                return Err(error_message(a, self.device).unwrap_or_else(|| "no RT filter".into()));
            }
            let image = |name: &CStr, data: *mut c_void| {
                (a.set_shared_filter_image)(
                    filter,
                    name.as_ptr(),
                    data,
                    FORMAT_FLOAT3,
                    width as usize,
                    height as usize,
                    0,
                    0,
                    0,
                )
            };
            image(c"color", color.as_mut_ptr().cast());
            image(c"albedo", albedo.as_ptr() as *mut c_void);
            image(c"normal", normal.as_ptr() as *mut c_void);
            image(c"output", output.as_mut_ptr().cast());
            (a.set_filter_bool)(filter, c"hdr".as_ptr(), true);
            (a.set_filter_bool)(filter, c"cleanAux".as_ptr(), true);
            (a.set_filter_int)(filter, c"quality".as_ptr(), self.quality.oidn());
            (a.commit_filter)(filter);
            let mut err = error_message(a, self.device);
            if err.is_none() {
                (a.execute_filter)(filter);
                err = error_message(a, self.device);
            }
            (a.release_filter)(filter);
            if let Some(e) = err {
                return Err(e);
            }
        }
        color.copy_from_slice(&output);
        Ok(())
    }

    /// Denoise a beauty frame in place with the frame's guides (`Guides`: albedo and normal):
    /// the asset's radiance, then (where the frame has a shadow catcher) the catcher's shadow, with
    /// alpha and the background made again from it. Pixels no sample of which hit the asset
    /// keep no radiance.
    pub fn denoise_beauty(&self, img: &mut BeautyImage) -> std::result::Result<(), String> {
        let mut color: Vec<[f32; 3]> = img.rgba.iter().map(|c| [c[0], c[1], c[2]]).collect();
        let albedo: Vec<[f32; 3]> = img.guides.iter().map(|g| g.albedo.to_array()).collect();
        let normal: Vec<[f32; 3]> = img.guides.iter().map(|g| g.normal.to_array()).collect();
        self.filter(img.width, img.height, &mut color, &albedo, &normal)?;
        // The device's preview was of the noisy pixels.
        img.preview = None;
        for ((c, d), g) in img.rgba.iter_mut().zip(&color).zip(&img.guides) {
            let keep = g.coverage > 0.0;
            for k in 0..3 {
                // The filter may leave a little radiance, or a negative lobe, beside the edges.
                c[k] = if keep { d[k].max(0.0) } else { 0.0 };
            }
        }
        self.denoise_catcher(img)
    }

    /// The shadow catcher's shadow, filtered as a grey image (its share of each pixel times
    /// the shadow), guided by that share (a white, flat ground); alpha and the background
    /// follow the filtered shadow. Nothing to do without a catcher in view. The filter runs in
    /// its HDR mode: in its LDR mode the sparse, all-or-nothing shadow of a few samples came
    /// out darker than the converged one (rock, 64², 4 spp: mean alpha 0.169 against 0.112,
    /// RMS 0.111; HDR: RMS 0.054, `tests/denoise.rs`).
    fn denoise_catcher(&self, img: &mut BeautyImage) -> std::result::Result<(), String> {
        if !img.guides.iter().any(|g| g.ground > 0.0 && g.shadow > 0.0) {
            return Ok(());
        }
        let mut color: Vec<[f32; 3]> = img
            .guides
            .iter()
            .map(|g| [g.ground * g.shadow; 3])
            .collect();
        let albedo: Vec<[f32; 3]> = img.guides.iter().map(|g| [g.ground; 3]).collect();
        let normal: Vec<[f32; 3]> = img.guides.iter().map(|g| [0.0, 0.0, g.ground]).collect();
        self.filter(img.width, img.height, &mut color, &albedo, &normal)?;
        for (((c, bg), g), d) in img
            .rgba
            .iter_mut()
            .zip(&mut img.background)
            .zip(&mut img.guides)
            .zip(&color)
        {
            if g.ground <= 0.0 {
                continue;
            }
            let shadow = ((d[0] + d[1] + d[2]) / (3.0 * g.ground)).clamp(0.0, 1.0);
            c[3] = g.coverage + g.ground * shadow;
            *bg += g.ground_background * (g.shadow - shadow);
            g.shadow = shadow;
        }
        Ok(())
    }
}

fn version_string(v: i32) -> String {
    format!("{}.{}.{}", v / 10000, (v / 100) % 100, v % 100)
}

/// The device's pending error for this thread, if any (and clears it).
///
/// # Safety
/// `device` is null or a device of the library `api` was resolved from.
unsafe fn error_message(api: &Api, device: DevicePtr) -> Option<String> {
    let mut msg: *const c_char = std::ptr::null();
    let code = (api.get_device_error)(device, &mut msg);
    if code == 0 {
        return None;
    }
    let text = if msg.is_null() {
        String::new()
    } else {
        CStr::from_ptr(msg).to_string_lossy().into_owned()
    };
    Some(format!("Open Image Denoise error {code}: {text}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_read_as_major_minor_patch() {
        assert_eq!(version_string(20303), "2.3.3");
        assert_eq!(version_string(20501), "2.5.1");
    }
}
