//! SSP packages: reading an .ssp archive, an SSP directory or an .ssd file.

use super::reader::parse_ssd_labelled;
use super::{Component, Error, System, SSD_FILE};
use crate::tmp::TempDir;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A read system: the structure and the directory its files are in (an unpacked .ssp in a
/// temporary directory, removed when the last package sharing it drops, or the directory given).
#[derive(Debug)]
pub struct Package {
    pub system: System,
    pub dir: PathBuf,
    /// The unpacked .ssp `dir` is, shared by the packages of [`Package::with_system`].
    pub(super) _temp: Option<Arc<TempDir>>,
}

impl Package {
    /// The same files with another structure (e.g. other start values), for runs that vary a
    /// system. It shares the unpacked files with `self`: they stay until both have dropped,
    /// whichever drops first.
    pub fn with_system(&self, system: System) -> Package {
        Package {
            system,
            dir: self.dir.clone(),
            _temp: self._temp.clone(),
        }
    }

    /// The file a component's `source` refers to.
    pub fn source_path(&self, c: &Component) -> PathBuf {
        let s = c.source.as_str();
        if let Some(abs) = s.strip_prefix("file://") {
            return PathBuf::from(abs);
        }
        self.dir.join(s.strip_prefix("./").unwrap_or(s))
    }
}

/// Read an .ssp archive (unpacked into a temporary directory), a directory holding
/// `SystemStructure.ssd`, or an `.ssd` file (its directory is the package directory).
pub fn read(path: &Path) -> Result<Package, Error> {
    let at = |e: Error| Error(format!("{}: {e}", path.display()));
    if path.is_dir() {
        let ssd = path.join(SSD_FILE);
        if !ssd.is_file() {
            return Err(at(Error(format!("not an SSP directory: no {SSD_FILE}"))));
        }
        let system = read_ssd_file(&ssd, path, SSD_FILE).map_err(at)?;
        return Ok(Package {
            system,
            dir: path.to_path_buf(),
            _temp: None,
        });
    }
    if path.extension().is_some_and(|e| e == "ssd") {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let label = path.display().to_string();
        let system = read_ssd_file(path, &dir, &label)?;
        return Ok(Package {
            system,
            dir,
            _temp: None,
        });
    }
    // Not a blocking open: a named pipe is refused at once (crate::archive::open_regular).
    let file =
        crate::archive::open_regular(path).map_err(|e| at(Error(format!("cannot open: {e}"))))?;
    let mut archive = zip::ZipArchive::new(file)
        .map_err(|e| at(Error(format!("not an SSP archive (zip): {e}"))))?;
    if archive.index_for_name(SSD_FILE).is_none() {
        return Err(at(Error(format!(
            "not an SSP: the archive has no {SSD_FILE} at its root"
        ))));
    }
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("ssp");
    let temp = TempDir::new(&format!("ssp-{stem}"))
        .map_err(|e| at(Error(format!("cannot unpack: {e}"))))?;
    crate::archive::unpack(&mut archive, path, temp.path(), |_| true).map_err(Error)?;
    let system = read_ssd_file(&temp.path().join(SSD_FILE), temp.path(), SSD_FILE).map_err(at)?;
    Ok(Package {
        system,
        dir: temp.path().to_path_buf(),
        _temp: Some(Arc::new(temp)),
    })
}

fn read_ssd_file(path: &Path, dir: &Path, label: &str) -> Result<System, Error> {
    let xml = crate::archive::read_text(path)
        .map_err(|e| Error(format!("{label}: cannot read {}: {e}", path.display())))?;
    parse_ssd_labelled(&xml, dir, label)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ssp::fixtures::*;

    /// A package made by `with_system` kept a directory that was removed when the original
    /// dropped; now they share it, and it goes with the last of them.
    #[test]
    fn a_package_with_another_system_keeps_the_unpacked_files() {
        let t = temp();
        let ssp = t.path().join("shared.ssp");
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&ssp).unwrap());
        let options = zip::write::SimpleFileOptions::default();
        zip.start_file(SSD_FILE, options).unwrap();
        let ssd = sample().to_ssd();
        std::io::Write::write_all(&mut zip, ssd.as_bytes()).unwrap();
        zip.start_file("resources/grid.fmu", options).unwrap();
        std::io::Write::write_all(&mut zip, b"grid bytes").unwrap();
        zip.finish().unwrap();
        let original = read(&ssp).unwrap();
        let mut system = original.system.clone();
        system.start_time = 1.5;
        let varied = original.with_system(system);
        let grid = varied.source_path(&varied.system.components[0]);
        drop(original);
        assert_eq!(std::fs::read(&grid).unwrap(), b"grid bytes");
        assert_eq!(varied.system.start_time, 1.5);
        let dir = varied.dir.clone();
        drop(varied);
        assert!(!dir.exists(), "removed with the last package");
    }

    #[test]
    fn not_an_ssp() {
        let t = temp();
        let junk = t.path().join("junk.ssp");
        std::fs::write(&junk, "hello").unwrap();
        let e = read(&junk).unwrap_err().0;
        assert!(
            e.contains("junk.ssp") && e.contains("not an SSP archive"),
            "{e}"
        );

        let empty = t.path().join("empty.ssp");
        let mut zip = zip::ZipWriter::new(std::fs::File::create(&empty).unwrap());
        zip.start_file("other.txt", zip::write::SimpleFileOptions::default())
            .unwrap();
        zip.finish().unwrap();
        let e = read(&empty).unwrap_err().0;
        assert!(e.contains("no SystemStructure.ssd"), "{e}");

        let e = read(t.path()).unwrap_err().0;
        assert!(e.contains("not an SSP directory"), "{e}");
        let e = read(&t.path().join("missing.ssp")).unwrap_err().0;
        assert!(
            e.contains("missing.ssp") && e.contains("cannot open"),
            "{e}"
        );
    }
}
