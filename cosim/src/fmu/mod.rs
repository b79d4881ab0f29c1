//! Loading an `.fmu`: unzip, read its modelDescription.xml, dlopen its binary, resolve the API.
//! FMUs whose binaries are identical (same `modelIdentifier`, same bytes) share one dlopen
//! ([`Library`]) and are instantiated from it many times, each with its own unpacked resources.

use crate::archive::unpack;
use model_description::ModelDescription;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};

pub use fmi2::Status;
use fmi2::{fmi2CallbackFunctions as CallbackFunctions, fmi2Component as Component};
use fmi2::{fmi2FMUstate as FmuState, Functions as Api};

extern "C" {
    /// The logger handed to FMUs (c/logger.c): formats the printf-style message with its
    /// arguments and passes the text on to [`dvpp_cosim_log_sink`].
    fn dvpp_cosim_logger(
        env: *mut c_void,
        instance: *const c_char,
        status: c_int,
        category: *const c_char,
        message: *const c_char,
        ...
    );
}

/// Names of the functions every FMI 2.0 Co-Simulation binary must export.
pub const FMI2_CS_FUNCTIONS: &[&str] = Api::NAMES;

/// A loaded FMU binary (the dlopen handle and its 34 functions), shared by every [`Fmu`] whose
/// binary has the same `modelIdentifier` and identical bytes; closed when the last one drops.
pub struct Library {
    model_identifier: String,
    api: Api,
    handle: *mut c_void,
    /// When offered for sharing: the binary, open (its directory may go before the library
    /// does), its length, and its bytes once a candidate of the same length was compared.
    offered: Option<Offered>,
}

struct Offered {
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
    fn open(
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

/// An unpacked FMU: its own directory and model description, and its binary (maybe shared).
pub struct Fmu {
    pub description: ModelDescription,
    /// Where the archive was unpacked (removed on drop).
    pub dir: PathBuf,
    library: Arc<Library>,
}

/// Why an FMU could not be loaded or used.
#[derive(Debug)]
pub struct Error(pub String);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

fn err<T>(m: impl Into<String>) -> Result<T, Error> {
    Err(Error(m.into()))
}

/// A loaded library identical to the archive's binary of `id`, if there is one.
fn twin_in(
    archive: &mut zip::ZipArchive<std::fs::File>,
    id: &str,
) -> Result<Option<Arc<Library>>, String> {
    let Ok(mut entry) = archive.by_name(&format!("binaries/linux64/{id}.so")) else {
        return Ok(None);
    };
    if candidates(id, entry.size()).is_empty() {
        return Ok(None);
    }
    let mut bytes = Vec::with_capacity(entry.size() as usize);
    std::io::Read::read_to_end(&mut entry, &mut bytes).map_err(|e| e.to_string())?;
    Ok(Fmu::twin(id, &bytes))
}

/// An unpacked FMU's model description, its `modelIdentifier` and whether it may share its
/// library (not `canBeInstantiatedOnlyOncePerProcess`).
fn describe(dir: &Path) -> Result<(ModelDescription, String, bool), Error> {
    let xml = crate::archive::read_text(&dir.join("modelDescription.xml"))
        .map_err(|e| Error(format!("modelDescription.xml: {e}")))?;
    let description = ModelDescription::from_xml(&xml).map_err(|e| Error(e.to_string()))?;
    let id = description
        .model_identifier()
        .map(str::to_owned)
        .ok_or_else(|| Error("the FMU does not support Co-Simulation".into()))?;
    let shareable = !description
        .co_simulation
        .as_ref()
        .is_some_and(|cs| cs.can_be_instantiated_only_once_per_process);
    Ok((description, id, shareable))
}

impl Fmu {
    /// Unpack `path` into a fresh temporary directory and load it, sharing its binary with
    /// FMUs already loaded whose binary is identical ([`Sharing::Shared`]).
    pub fn load(path: &Path) -> Result<Fmu, Error> {
        Fmu::load_with(path, Sharing::Shared)
    }

    /// [`Fmu::load`] with a choice of sharing. With [`Sharing::Shared`], an FMU whose binary
    /// is identical to one already loaded is unpacked without its `binaries/` (the model
    /// description and resources are what its instances use): a thousand copies of one FMU
    /// write one binary to disk, not a thousand.
    pub fn load_with(path: &Path, sharing: Sharing) -> Result<Fmu, Error> {
        let at = |e: String| Error(format!("{}: {e}", path.display()));
        let file = std::fs::File::open(path)
            .map_err(|e| Error(format!("cannot open {}: {e}", path.display())))?;
        let mut archive = zip::ZipArchive::new(file)
            .map_err(|e| Error(format!("{} is not an FMU archive: {e}", path.display())))?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("fmu");
        let dir = crate::tmp::create_dir(&format!("fmu-{stem}"))
            .map_err(|e| Error(format!("cannot unpack {}: {e}", path.display())))?;
        let binaries = |name: &str| name.starts_with("binaries/");
        // The directory is ours from here: removed on every error, as by Drop.
        let fail = |dir: &Path, e: String| {
            let _ = std::fs::remove_dir_all(dir);
            Err(at(e))
        };
        // Unpacking errors name the archive and the entry already.
        let unpacked = |dir: &Path, e: String| {
            let _ = std::fs::remove_dir_all(dir);
            Err(Error(e))
        };
        if let Err(e) = unpack(&mut archive, path, &dir, |n| !binaries(n)) {
            return unpacked(&dir, e);
        }
        let (description, id, shareable) = match describe(&dir) {
            Ok(d) => d,
            Err(e) => return fail(&dir, e.0),
        };
        if sharing == Sharing::Shared && shareable {
            match twin_in(&mut archive, &id) {
                Ok(Some(library)) => {
                    return Ok(Fmu {
                        description,
                        dir,
                        library,
                    })
                }
                Ok(None) => {}
                Err(e) => return fail(&dir, format!("cannot unpack: {e}")),
            }
        }
        if let Err(e) = unpack(&mut archive, path, &dir, binaries) {
            return unpacked(&dir, e);
        }
        Fmu::with_library(dir, (description, id, shareable), sharing).map_err(|e| at(e.0))
    }

    /// Load an FMU already unpacked in `dir` (the directory is removed when the `Fmu` drops, or
    /// at once when it cannot be loaded).
    pub fn load_dir(dir: PathBuf) -> Result<Fmu, Error> {
        Fmu::load_dir_with(dir, Sharing::Shared)
    }

    /// [`Fmu::load_dir`] with a choice of sharing. The directory stays a complete unpacked FMU
    /// either way (its binary too, even when the library of another FMU serves it).
    pub fn load_dir_with(dir: PathBuf, sharing: Sharing) -> Result<Fmu, Error> {
        match describe(&dir) {
            Ok(described) => Fmu::with_library(dir, described, sharing),
            Err(e) => {
                let _ = std::fs::remove_dir_all(&dir);
                Err(e)
            }
        }
    }

    /// The described FMU unpacked in `dir` with its binary loaded (or shared); `dir` is removed
    /// on error.
    fn with_library(
        dir: PathBuf,
        (description, id, shareable): (ModelDescription, String, bool),
        sharing: Sharing,
    ) -> Result<Fmu, Error> {
        let fail = |dir: &Path, e: Error| {
            let _ = std::fs::remove_dir_all(dir);
            Err(e)
        };
        let binary = dir
            .join("binaries")
            .join("linux64")
            .join(format!("{id}.so"));
        if !binary.is_file() {
            return fail(
                &dir,
                Error(format!("missing binary binaries/linux64/{id}.so")),
            );
        }
        let library = if sharing == Sharing::Shared && shareable {
            Fmu::shared_library(&binary, &id)
        } else {
            Library::open(&binary, &id, None).map(Arc::new)
        };
        match library {
            Ok(library) => Ok(Fmu {
                description,
                dir,
                library,
            }),
            Err(e) => fail(&dir, e),
        }
    }

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
    fn shared_library(binary: &Path, id: &str) -> Result<Arc<Library>, Error> {
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

    /// The loaded binary this FMU's instances run in.
    pub fn library(&self) -> &Arc<Library> {
        &self.library
    }

    /// Whether this FMU and `other` run in one loaded library (one dlopen).
    pub fn shares_library_with(&self, other: &Fmu) -> bool {
        Arc::ptr_eq(&self.library, &other.library)
    }

    /// The `file://` URI of the unpacked `resources/` directory, percent-encoded.
    pub fn resource_uri(&self) -> String {
        let path = self.dir.join("resources");
        let mut uri = String::from("file://");
        for b in path.to_string_lossy().bytes() {
            if b.is_ascii_alphanumeric() || b"/-_.~".contains(&b) {
                uri.push(b as char);
            } else {
                uri.push_str(&format!("%{b:02X}"));
            }
        }
        uri
    }

    /// `fmi2GetVersion` and `fmi2GetTypesPlatform`.
    pub fn version_and_platform(&self) -> (String, String) {
        // SAFETY: both return static C strings.
        unsafe {
            let v = CStr::from_ptr((self.library.api.get_version)())
                .to_string_lossy()
                .into_owned();
            let p = CStr::from_ptr((self.library.api.get_types_platform)())
                .to_string_lossy()
                .into_owned();
            (v, p)
        }
    }

    /// Value reference of the variable `name`.
    pub fn vr(&self, name: &str) -> Result<u32, Error> {
        self.description
            .variable(name)
            .map(|v| v.value_reference)
            .ok_or_else(|| {
                Error(format!(
                    "{} has no variable '{name}'",
                    self.description.model_name
                ))
            })
    }

    /// Instantiate with the description's GUID and the unpacked resources.
    pub fn instantiate(self: &Arc<Self>, name: &str) -> Result<Instance, Error> {
        let guid = self.description.guid.clone();
        self.instantiate_with(name, &guid, &self.resource_uri(), 1)
    }

    /// Instantiate with explicit GUID, resource URI and `fmuType` (for tests of bad calls).
    pub fn instantiate_with(
        self: &Arc<Self>,
        name: &str,
        guid: &str,
        resources: &str,
        fmu_type: i32,
    ) -> Result<Instance, Error> {
        let sink = Box::new(LogSink {
            instance: name.to_owned(),
            records: Mutex::new(Vec::new()),
            held: AtomicUsize::new(0),
            echo: std::env::var_os("DVPP_FMU_LOG").is_some(),
        });
        let sink_ptr = Box::into_raw(sink);
        let callbacks = Box::new(CallbackFunctions {
            logger: Some(dvpp_cosim_logger),
            allocate_memory: Some(alloc_callback),
            free_memory: Some(free_callback),
            step_finished: None,
            component_environment: sink_ptr as *mut c_void,
        });
        let (c_name, c_guid, c_res) = (cstring(name)?, cstring(guid)?, cstring(resources)?);
        // SAFETY: valid C strings and a callbacks struct that lives as long as the instance.
        let component = unsafe {
            (self.library.api.instantiate)(
                c_name.as_ptr(),
                fmu_type,
                c_guid.as_ptr(),
                c_res.as_ptr(),
                &*callbacks,
                0,
                0,
            )
        };
        // SAFETY: we own the sink until the instance is dropped.
        let sink = unsafe { Box::from_raw(sink_ptr) };
        if component.is_null() {
            let last = sink
                .records
                .lock()
                .unwrap()
                .last()
                .map(|r| r.message.clone())
                .unwrap_or_default();
            return err(format!("fmi2Instantiate of '{name}' returned NULL: {last}"));
        }
        Ok(Instance {
            fmu: Arc::clone(self),
            component,
            sink,
            callbacks,
        })
    }
}

impl Drop for Fmu {
    fn drop(&mut self) {
        // The library closes when its last FMU drops (Library's Drop).
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn cstring(s: &str) -> Result<CString, Error> {
    CString::new(s).map_err(|_| Error(format!("'{s}' contains a NUL byte")))
}

/// One message an FMU logged.
#[derive(Debug, Clone)]
pub struct LogRecord {
    pub status: Status,
    pub category: String,
    pub message: String,
}

/// Where one instance's log messages go. Thread-safe: each instance has its own sink, the
/// records sit behind a mutex, the C shim formats into its own heap buffer, and echoed lines go
/// through the locked stderr; instances stepping in parallel threads log independently.
struct LogSink {
    instance: String,
    records: Mutex<Vec<LogRecord>>,
    /// How many records are held, so that taking none needs no lock (the master asks after
    /// every FMI call).
    held: AtomicUsize,
    echo: bool,
}

/// Records one message already formatted by `dvpp_cosim_logger` (c/logger.c); never unwinds.
#[no_mangle]
unsafe extern "C" fn dvpp_cosim_log_sink(
    env: *mut c_void,
    name: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    // A panic (e.g. stderr gone) must not unwind into the FMU's C frames: drop the message.
    // SAFETY: the arguments as the FMU passed them (see `log_sink`).
    let _ = std::panic::catch_unwind(|| unsafe { log_sink(env, name, status, category, message) });
}

/// Record one message of an FMU.
///
/// # Safety
/// `env` is NULL or the `LogSink` this master gave the instance as its environment, alive while
/// the instance is; `category` and `message` are NULL or NUL-terminated strings.
unsafe fn log_sink(
    env: *mut c_void,
    _name: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    // SAFETY: NULL or our live `LogSink` (the contract above).
    let Some(sink) = (unsafe { (env as *const LogSink).as_ref() }) else {
        return;
    };
    let text = |p: *const c_char| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: a non-null NUL-terminated string (the contract above).
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    // The C shim already substituted the printf arguments (and turned `%%` into `%`).
    let record = LogRecord {
        status: Status::from_c(status),
        category: text(category),
        message: text(message),
    };
    if sink.echo {
        eprintln!(
            "[{}] {:?} {}: {}",
            sink.instance, record.status, record.category, record.message
        );
    }
    if let Ok(mut r) = sink.records.lock() {
        r.push(record);
        sink.held.store(r.len(), Ordering::Release);
    }
}

unsafe extern "C" fn alloc_callback(n: usize, size: usize) -> *mut c_void {
    // SAFETY: calloc accepts any sizes (NULL when it cannot).
    unsafe { libc::calloc(n, size) }
}

unsafe extern "C" fn free_callback(p: *mut c_void) {
    // SAFETY: the FMU frees what `alloc_callback` gave it (or NULL), as FMI 2.0 requires.
    unsafe { libc::free(p) }
}

/// An instance of a loaded FMU; freed on drop.
pub struct Instance {
    fmu: Arc<Fmu>,
    component: Component,
    sink: Box<LogSink>,
    callbacks: Box<CallbackFunctions>,
}

// SAFETY: an FMI 2.0 instance shares no state with the other instances of its binary through
// the API (each has its own component, callbacks and log sink), and the master calls each
// instance from one thread at a time (`&mut self` on every call that reaches the FMU), so an
// instance may move to another thread between calls, which is what parallel stepping does.
// That instances of one binary may step in parallel threads at all is the FMU's property:
// ours keep no global mutable state (tested); `--threads` is the user's choice for others.
unsafe impl Send for Instance {}

/// A saved FMU state; must be freed through the instance that made it.
pub struct SavedState(FmuState);

impl Instance {
    pub fn fmu(&self) -> &Arc<Fmu> {
        &self.fmu
    }

    /// Everything the FMU logged so far.
    pub fn log(&self) -> Vec<LogRecord> {
        self.sink
            .records
            .lock()
            .map(|r| r.clone())
            .unwrap_or_default()
    }

    /// Whether the FMU logged anything since the last [`Instance::take_log`] (one atomic load:
    /// the master asks after every call).
    #[inline]
    pub fn has_log(&self) -> bool {
        self.sink.held.load(Ordering::Acquire) != 0
    }

    /// The messages logged since the last call (they are removed from the record).
    pub fn take_log(&self) -> Vec<LogRecord> {
        if self.sink.held.load(Ordering::Acquire) == 0 {
            return Vec::new();
        }
        self.sink
            .records
            .lock()
            .map(|mut r| {
                self.sink.held.store(0, Ordering::Release);
                std::mem::take(&mut *r)
            })
            .unwrap_or_default()
    }

    /// The last message the FMU logged.
    pub fn last_message(&self) -> Option<String> {
        self.sink
            .records
            .lock()
            .ok()?
            .last()
            .map(|r| r.message.clone())
    }

    fn api(&self) -> &Api {
        &self.fmu.library.api
    }

    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Status {
        let c: Vec<CString> = categories
            .iter()
            .map(|s| CString::new(*s).unwrap())
            .collect();
        let p: Vec<*const c_char> = c.iter().map(|s| s.as_ptr()).collect();
        // SAFETY: arrays of the stated length.
        Status::from_c(unsafe {
            (self.api().set_debug_logging)(self.component, on as c_int, p.len(), p.as_ptr())
        })
    }

    pub fn setup_experiment(&mut self, start: f64, stop: Option<f64>) -> Status {
        // SAFETY: plain values.
        Status::from_c(unsafe {
            (self.api().setup_experiment)(
                self.component,
                0,
                0.0,
                start,
                stop.is_some() as c_int,
                stop.unwrap_or(0.0),
            )
        })
    }

    pub fn enter_initialization_mode(&mut self) -> Status {
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().enter_initialization_mode)(self.component) })
    }

    pub fn exit_initialization_mode(&mut self) -> Status {
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().exit_initialization_mode)(self.component) })
    }

    pub fn terminate(&mut self) -> Status {
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().terminate)(self.component) })
    }

    pub fn reset(&mut self) -> Status {
        // SAFETY: valid component.
        Status::from_c(unsafe { (self.api().reset)(self.component) })
    }

    pub fn get_real(&mut self, vrs: &[u32], out: &mut [f64]) -> Status {
        assert_eq!(vrs.len(), out.len());
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().get_real)(self.component, vrs.as_ptr(), vrs.len(), out.as_mut_ptr())
        })
    }

    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> Status {
        assert_eq!(vrs.len(), values.len());
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_real)(self.component, vrs.as_ptr(), vrs.len(), values.as_ptr())
        })
    }

    pub fn get_integer(&mut self, vrs: &[u32], out: &mut [i32]) -> Status {
        assert_eq!(vrs.len(), out.len());
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().get_integer)(self.component, vrs.as_ptr(), vrs.len(), out.as_mut_ptr())
        })
    }

    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) -> Status {
        assert_eq!(vrs.len(), values.len());
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_integer)(self.component, vrs.as_ptr(), vrs.len(), values.as_ptr())
        })
    }

    pub fn get_boolean(&mut self, vrs: &[u32], out: &mut [bool]) -> Status {
        let mut raw = vec![0; vrs.len()];
        // SAFETY: arrays of equal, stated length.
        let s = Status::from_c(unsafe {
            (self.api().get_boolean)(self.component, vrs.as_ptr(), vrs.len(), raw.as_mut_ptr())
        });
        for (o, r) in out.iter_mut().zip(raw) {
            *o = r != 0;
        }
        s
    }

    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> Status {
        let raw: Vec<c_int> = values.iter().map(|&b| b as c_int).collect();
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_boolean)(self.component, vrs.as_ptr(), vrs.len(), raw.as_ptr())
        })
    }

    pub fn get_string(&mut self, vrs: &[u32]) -> (Status, Vec<String>) {
        let mut raw = vec![std::ptr::null(); vrs.len()];
        // SAFETY: arrays of equal length; strings copied before the next call.
        unsafe {
            let s = Status::from_c((self.api().get_string)(
                self.component,
                vrs.as_ptr(),
                vrs.len(),
                raw.as_mut_ptr(),
            ));
            let v = raw
                .iter()
                .map(|&p| {
                    if p.is_null() {
                        String::new()
                    } else {
                        CStr::from_ptr(p).to_string_lossy().into_owned()
                    }
                })
                .collect();
            (s, v)
        }
    }

    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) -> Status {
        let c: Vec<CString> = values.iter().map(|s| CString::new(*s).unwrap()).collect();
        let p: Vec<*const c_char> = c.iter().map(|s| s.as_ptr()).collect();
        // SAFETY: arrays of equal, stated length.
        Status::from_c(unsafe {
            (self.api().set_string)(self.component, vrs.as_ptr(), vrs.len(), p.as_ptr())
        })
    }

    pub fn do_step(&mut self, t: f64, h: f64) -> Status {
        // SAFETY: plain values.
        Status::from_c(unsafe { (self.api().do_step)(self.component, t, h, 1) })
    }

    /// `fmi2GetFMUstate` into a new state.
    pub fn get_state(&mut self) -> (Status, Option<SavedState>) {
        let mut s: FmuState = std::ptr::null_mut();
        // SAFETY: out-pointer to a null state asks for a new one.
        let status = Status::from_c(unsafe { (self.api().get_fmu_state)(self.component, &mut s) });
        (status, (!s.is_null()).then_some(SavedState(s)))
    }

    /// `fmi2GetFMUstate` into a state this FMU made before (overwritten, no allocation).
    pub fn update_state(&mut self, s: &mut SavedState) -> Status {
        // SAFETY: out-pointer to a state of this FMU asks for an overwrite.
        Status::from_c(unsafe { (self.api().get_fmu_state)(self.component, &mut s.0) })
    }

    pub fn set_state(&mut self, s: &SavedState) -> Status {
        // SAFETY: a state this FMU made.
        Status::from_c(unsafe { (self.api().set_fmu_state)(self.component, s.0) })
    }

    pub fn free_state(&mut self, mut s: SavedState) -> Status {
        // SAFETY: a state this FMU made; freed once.
        Status::from_c(unsafe { (self.api().free_fmu_state)(self.component, &mut s.0) })
    }

    /// Serialize a saved state to bytes.
    pub fn serialize_state(&mut self, s: &SavedState) -> Result<Vec<u8>, Status> {
        let mut size = 0usize;
        // SAFETY: out-pointers valid; buffer of the reported size.
        unsafe {
            let st = Status::from_c((self.api().serialized_fmu_state_size)(
                self.component,
                s.0,
                &mut size,
            ));
            if st > Status::Warning {
                return Err(st);
            }
            let mut buf = vec![0u8; size];
            let st = Status::from_c((self.api().serialize_fmu_state)(
                self.component,
                s.0,
                buf.as_mut_ptr() as *mut c_char,
                size,
            ));
            if st > Status::Warning {
                return Err(st);
            }
            Ok(buf)
        }
    }

    /// Turn bytes back into a saved state of this instance.
    pub fn deserialize_state(&mut self, bytes: &[u8]) -> (Status, Option<SavedState>) {
        let mut s: FmuState = std::ptr::null_mut();
        // SAFETY: buffer of the stated length; out-pointer to a null state.
        let st = Status::from_c(unsafe {
            (self.api().deserialize_fmu_state)(
                self.component,
                bytes.as_ptr() as *const c_char,
                bytes.len(),
                &mut s,
            )
        });
        (st, (!s.is_null()).then_some(SavedState(s)))
    }

    /// Call each optional function this project's FMUs do not provide; returns their statuses.
    pub fn call_unsupported(&mut self) -> Vec<(&'static str, Status)> {
        let (vr, order, mut x) = ([0u32], [1 as c_int], [0.0f64]);
        // SAFETY: one-element arrays as stated.
        unsafe {
            let a = self.api();
            vec![
                (
                    "fmi2GetDirectionalDerivative",
                    (a.get_directional_derivative)(
                        self.component,
                        vr.as_ptr(),
                        1,
                        vr.as_ptr(),
                        1,
                        x.as_ptr(),
                        x.as_mut_ptr(),
                    ),
                ),
                (
                    "fmi2SetRealInputDerivatives",
                    (a.set_real_input_derivatives)(
                        self.component,
                        vr.as_ptr(),
                        1,
                        order.as_ptr(),
                        x.as_ptr(),
                    ),
                ),
                (
                    "fmi2GetRealOutputDerivatives",
                    (a.get_real_output_derivatives)(
                        self.component,
                        vr.as_ptr(),
                        1,
                        order.as_ptr(),
                        x.as_mut_ptr(),
                    ),
                ),
                ("fmi2CancelStep", (a.cancel_step)(self.component)),
            ]
            .into_iter()
            .map(|(n, s)| (n, Status::from_c(s)))
            .collect()
        }
    }

    /// `fmi2GetRealStatus(fmi2LastSuccessfulTime)` and `fmi2GetBooleanStatus(fmi2Terminated)`.
    pub fn last_successful_time(&mut self) -> (Status, f64) {
        let mut t = f64::NAN;
        // SAFETY: out-pointer valid.
        let s = Status::from_c(unsafe { (self.api().get_real_status)(self.component, 2, &mut t) });
        (s, t)
    }

    /// Statuses the FMU reports for the other status queries (integer, string, boolean, status).
    pub fn status_queries(&mut self) -> Vec<Status> {
        let (mut i, mut b, mut st) = (0, 0, 0);
        let mut s: *const c_char = std::ptr::null();
        // SAFETY: out-pointers valid.
        unsafe {
            let a = self.api();
            vec![
                Status::from_c((a.get_status)(self.component, 0, &mut st)),
                Status::from_c((a.get_integer_status)(self.component, 0, &mut i)),
                Status::from_c((a.get_boolean_status)(self.component, 3, &mut b)),
                Status::from_c((a.get_string_status)(self.component, 1, &mut s)),
            ]
        }
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        // SAFETY: the component is valid and freed once; callbacks outlive it.
        unsafe { (self.fmu.library.api.free_instance)(self.component) };
        let _ = &self.callbacks;
    }
}
