//! Loading an FMU: unpacking the archive, its model description, its binary (own or shared).

use super::library::{twin_in, Library, Sharing};
use super::Error;
use crate::archive::unpack;
use model_description::ModelDescription;
use std::ffi::CStr;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// An unpacked FMU: its own directory and model description, and its binary (maybe shared).
pub struct Fmu {
    pub description: ModelDescription,
    /// Where the archive was unpacked (removed on drop).
    pub dir: PathBuf,
    pub(super) library: Arc<Library>,
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
        // Not a blocking open: a named pipe is refused at once (crate::archive::open_regular).
        let file = crate::archive::open_regular(path)
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
}

impl Drop for Fmu {
    fn drop(&mut self) {
        // The library closes when its last FMU drops (Library's Drop).
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
