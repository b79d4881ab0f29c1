//! Loaded FMU binaries and their sharing: one dlopen per distinct binary, process-wide.

use super::{err, Error, Fmu};
use std::ffi::{c_void, CStr, CString};
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock, Weak};

use fmi2::Functions as Api;

/// A loaded FMU binary (the dlopen handle and its 34 functions), shared by every [`Fmu`] whose
/// binary has the same `modelIdentifier` and identical bytes; closed when the last one drops.
pub struct Library {
    model_identifier: String,
    pub(super) api: Api,
    handle: *mut c_void,
    /// When offered for sharing: the binary, open (its directory may go before the library
    /// does), its length, and its bytes once a candidate of the same length was compared.
    offered: Option<Offered>,
}

pub(super) struct Offered {
    file: std::fs::File,
    len: u64,
    bytes: OnceLock<std::io::Result<Vec<u8>>>,
}

impl Offered {
    /// The bytes of the offered binary (read on the first comparison).
    fn bytes(&self) -> Option<&[u8]> {
        use std::os::unix::fs::FileExt;
        let read = || {
            let mut buf = vec![0; self.len as usize];
            self.file.read_exact_at(&mut buf, 0).map(|()| buf)
        };
        self.bytes.get_or_init(read).as_deref().ok()
    }
}

// SAFETY: the handle and the function pointers are plain addresses that any thread may use;
// the library's functions are called per instance (see `Instance`), never through `Library`.
unsafe impl Send for Library {}
// SAFETY: as for `Send`: nothing in `Library` is mutated through a shared reference.
unsafe impl Sync for Library {}

impl Library {
    /// The `modelIdentifier` of the FMUs using this binary.
    pub fn model_identifier(&self) -> &str {
        &self.model_identifier
    }

    /// dlopen `path` and resolve the API.
    pub(super) fn open(
        path: &Path,
        model_identifier: &str,
        offered: Option<Offered>,
    ) -> Result<Library, Error> {
        let c_path = CString::new(path.to_string_lossy().as_bytes())
            .map_err(|_| Error("bad path".into()))?;
        // SAFETY: dlopen/dlsym with valid C strings; the handle is closed in Drop.
        unsafe {
            let handle = libc::dlopen(c_path.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL);
            if handle.is_null() {
                let why = CStr::from_ptr(libc::dlerror())
                    .to_string_lossy()
                    .into_owned();
                return err(format!("cannot load {}: {why}", path.display()));
            }
            // The symbols of an FMI 2.0 binary have the ABI's types (what loading an FMU
            // assumes); they live until the handle is closed in Drop.
            let api = Api::resolve(|name| libc::dlsym(handle, name.as_ptr()))
                .map_err(|missing| format!("the binary does not export {missing}"));
            match api {
                Ok(api) => Ok(Library {
                    model_identifier: model_identifier.to_owned(),
                    api,
                    handle,
                    offered,
                }),
                Err(e) => {
                    libc::dlclose(handle);
                    err(e)
                }
            }
        }
    }
}

impl Drop for Library {
    fn drop(&mut self) {
        // SAFETY: every Instance holds an Arc<Fmu> holding this library, so none is alive here.
        unsafe { libc::dlclose(self.handle) };
    }
}

/// Whether components with identical binaries share one loaded library.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sharing {
    /// One dlopen per distinct binary (same `modelIdentifier`, byte-identical file), however
    /// many components use it; each instance still gets its own unpacked resources. FMUs that
    /// declare `canBeInstantiatedOnlyOncePerProcess` always get their own copy.
    #[default]
    Shared,
    /// Every FMU dlopens its own unpacked copy of its binary (how the master loaded before).
    Separate,
}

/// The libraries offered for sharing, process-wide; a dead entry is pruned on the next load.
static LIBRARIES: Mutex<Vec<Weak<Library>>> = Mutex::new(Vec::new());

/// The live libraries offered with this identifier and length (the candidates to compare).
fn candidates(id: &str, len: u64) -> Vec<Arc<Library>> {
    let mut libraries = LIBRARIES.lock().unwrap_or_else(|e| e.into_inner());
    libraries.retain(|w| w.strong_count() > 0);
    libraries
        .iter()
        .filter_map(Weak::upgrade)
        .filter(|l| l.model_identifier == id && l.offered.as_ref().is_some_and(|o| o.len == len))
        .collect()
}

/// A loaded library identical to the archive's binary of `id`, if there is one.
pub(super) fn twin_in(
    archive: &mut zip::ZipArchive<std::fs::File>,
    id: &str,
) -> Result<Option<Arc<Library>>, String> {
    let Ok(mut entry) = archive.by_name(&format!("binaries/linux64/{id}.so")) else {
        return Ok(None);
    };
    if candidates(id, entry.size()).is_empty() {
        return Ok(None);
    }
    // The archive's sizes were checked (crate::archive::check_sizes) before this is called;
    // the data may still inflate to more than the entry declares: read one byte past it.
    let declared = entry.size();
    let mut bytes = Vec::with_capacity(declared as usize);
    std::io::Read::read_to_end(
        &mut std::io::Read::take(&mut entry, declared + 1),
        &mut bytes,
    )
    .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > declared {
        return Err(format!(
            "binaries/linux64/{id}.so holds more than the {declared} bytes it declares"
        ));
    }
    Ok(Fmu::twin(id, &bytes))
}

impl Fmu {
    /// A live library offered with identifier `id` whose binary is `bytes`, byte for byte.
    fn twin(id: &str, bytes: &[u8]) -> Option<Arc<Library>> {
        candidates(id, bytes.len() as u64).into_iter().find(|l| {
            l.offered
                .as_ref()
                .and_then(Offered::bytes)
                .is_some_and(|b| b == bytes)
        })
    }

    /// The library already loaded from identical bytes, or `binary` loaded and offered for
    /// sharing. The bytes are compared in full (not by a hash, which could collide), and only
    /// with libraries of the same identifier and length: a binary without such a twin is not
    /// read at all. Two threads loading twins at the same moment may each load their own
    /// (unshared, never wrong).
    pub(super) fn shared_library(binary: &Path, id: &str) -> Result<Arc<Library>, Error> {
        let at = |e: std::io::Error| Error(format!("cannot read {}: {e}", binary.display()));
        let file = std::fs::File::open(binary).map_err(at)?;
        let len = file.metadata().map_err(at)?.len();
        let bytes = OnceLock::new();
        if !candidates(id, len).is_empty() {
            let mine = std::fs::read(binary).map_err(at)?;
            if let Some(l) = Fmu::twin(id, &mine) {
                return Ok(l);
            }
            let _ = bytes.set(Ok(mine));
        }
        let offered = Offered { file, len, bytes };
        let library = Arc::new(Library::open(binary, id, Some(offered))?);
        LIBRARIES
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(Arc::downgrade(&library));
        Ok(library)
    }
}
