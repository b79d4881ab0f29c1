//! Private temporary directories: fresh, unpredictable names, owner-only, never reused.
//!
//! Every directory the master, the federation and the tests unpack into comes from
//! [`create_dir`]: `$TMPDIR/dvpp-<label>-<random>` made by `mkdir` with mode 0700, which fails
//! when the name exists (a directory, a file or a symbolic link planted by someone else), so a
//! directory is always created, never reused and never reached through a link. The random part
//! (128 bits from the kernel's `getrandom`, or `/dev/urandom`) keeps the name from being guessed
//! beforehand. [`TempDir`] removes its directory on drop.

use std::io;
use std::os::unix::fs::DirBuilderExt;
use std::path::{Path, PathBuf};

/// `bytes.len()` random bytes from the kernel.
fn random(bytes: &mut [u8]) -> io::Result<()> {
    let mut filled = 0;
    while filled < bytes.len() {
        let rest = &mut bytes[filled..];
        // SAFETY: a valid writable buffer of `rest.len()` bytes.
        let n = unsafe { libc::getrandom(rest.as_mut_ptr().cast(), rest.len(), 0) };
        if n > 0 {
            filled += n as usize;
            continue;
        }
        let e = io::Error::last_os_error();
        match e.raw_os_error() {
            Some(libc::EINTR) => continue,
            // A kernel without getrandom(2): the device gives the same bytes.
            Some(libc::ENOSYS) => {
                use std::io::Read;
                return std::fs::File::open("/dev/urandom")?.read_exact(rest);
            }
            _ => return Err(e),
        }
    }
    Ok(())
}

/// `label` reduced to a short file name part (ASCII letters, digits, `-`, `_`).
fn clean(label: &str) -> String {
    label
        .chars()
        .take(48)
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Create a fresh directory `dvpp-<label>-<32 random hex digits>` in `parent` with mode 0700.
pub fn create_dir_in(parent: &Path, label: &str) -> io::Result<PathBuf> {
    let label = clean(label);
    let mut last = None;
    // A name that exists already is never used; a few fresh draws make a collision moot.
    for _ in 0..8 {
        let mut bytes = [0u8; 16];
        random(&mut bytes)?;
        let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
        let dir = parent.join(format!("dvpp-{label}-{hex}"));
        match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
            Err(e) => {
                return Err(io::Error::new(
                    e.kind(),
                    format!("cannot create a directory in {}: {e}", parent.display()),
                ))
            }
        }
    }
    Err(last.unwrap_or_else(|| io::Error::other("no fresh name")))
}

/// Create a fresh private directory in the system's temporary directory ([`create_dir_in`]).
pub fn create_dir(label: &str) -> io::Result<PathBuf> {
    create_dir_in(&std::env::temp_dir(), label)
}

/// A fresh private temporary directory, removed (with its contents) on drop.
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl TempDir {
    /// A directory from [`create_dir`].
    pub fn new(label: &str) -> io::Result<TempDir> {
        create_dir(label).map(TempDir)
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// Keep the directory: the caller removes it.
    pub fn into_path(self) -> PathBuf {
        let path = self.0.clone();
        std::mem::forget(self);
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    #[test]
    fn directories_are_fresh_private_and_unpredictable() {
        let a = TempDir::new("t/../x y").unwrap();
        let b = TempDir::new("t/../x y").unwrap();
        assert_ne!(a.path(), b.path());
        let name = a.path().file_name().unwrap().to_str().unwrap().to_owned();
        assert!(name.starts_with("dvpp-t____x_y-"), "{name}");
        assert_eq!(name.len(), "dvpp-t____x_y-".len() + 32, "{name}");
        let meta = std::fs::symlink_metadata(a.path()).unwrap();
        assert!(meta.is_dir());
        assert_eq!(meta.permissions().mode() & 0o777, 0o700);
        let gone = a.path().to_path_buf();
        drop(a);
        assert!(!gone.exists());
    }
}
