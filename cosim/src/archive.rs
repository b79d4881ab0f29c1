//! Unpacking FMU and SSP archives without trusting their entries, and bounded reads of the files
//! a package names.
//!
//! [`unpack`] writes regular files and directories only, each created new (`O_EXCL`) and
//! without following links; an entry that is a symbolic link, a device, a pipe or a socket, or
//! whose name is absolute or climbs out with `..`, is refused with the archive's and the
//! entry's names. Before a byte is written, the sizes the archive declares are checked against
//! [`MAX_UNPACKED`] (all entries together) and [`MAX_RATIO`] (each entry's unpacked size to its
//! compressed size), so that a zip bomb is refused without being inflated; while writing, an
//! entry that inflates to more than it declared is cut there and refused. [`open_regular`]
//! opens an archive or package file without waiting on a named pipe, and [`read_text`] reads a
//! file of a package (a model description, an SSD, a parameter file) only if it is a regular
//! file of at most [`MAX_FILE`] bytes.

use std::io::{self, Read};
use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
use std::path::{Component, Path, PathBuf};

/// The largest package file [`read_text`] reads (a model description, SSD or parameter file).
pub const MAX_FILE: u64 = 16 << 20;

/// The most bytes one archive may unpack to, all its entries together: 1 GiB. An FMU of this
/// project unpacks to a few MB, an SSP with its FMUs to some tens of MB; a thousandfold margin
/// still keeps a hostile archive from filling the disk (every FMU of a system is unpacked).
pub const MAX_UNPACKED: u64 = 1 << 30;

/// The largest ratio of an entry's unpacked size to its compressed size: 100 to 1, for entries
/// of more than [`RATIO_FROM`] bytes. Binaries compress about 3:1 and XML or tables 5-20:1;
/// ratios near deflate's limit (about 1000:1) are runs of one byte, which is what a zip bomb is
/// made of (10 MB of zeros deflate to 10 kB).
pub const MAX_RATIO: u64 = 100;

/// Entries up to this size (1 MiB) are not held to [`MAX_RATIO`]: a small file of repeated
/// bytes is harmless, and [`MAX_UNPACKED`] bounds them all.
pub const RATIO_FROM: u64 = 1 << 20;

const S_IFMT: u32 = 0o170000;
const S_IFREG: u32 = 0o100000;
const S_IFDIR: u32 = 0o040000;

/// What an entry's Unix mode says it is, when it is not a file or a directory.
fn special(mode: u32) -> Option<&'static str> {
    match mode & S_IFMT {
        0 | S_IFREG | S_IFDIR => None,
        0o120000 => Some("a symbolic link"),
        0o020000 => Some("a character device"),
        0o060000 => Some("a block device"),
        0o010000 => Some("a named pipe"),
        0o140000 => Some("a socket"),
        _ => Some("not a regular file"),
    }
}

/// The relative path of entry `name` inside the directory, or why it has none.
fn relative(name: &str) -> Result<PathBuf, &'static str> {
    if name.contains('\0') {
        return Err("has a NUL byte in its name");
    }
    if name.starts_with('/') || name.starts_with('\\') || name.get(1..2) == Some(":") {
        return Err("has an absolute path");
    }
    let mut out = PathBuf::new();
    for part in Path::new(name).components() {
        match part {
            Component::Normal(p) if p.to_str().is_some_and(|s| s.contains('\\')) => {
                return Err("has a backslash in its name")
            }
            Component::Normal(p) => out.push(p),
            Component::CurDir => {}
            Component::ParentDir => return Err("leaves the directory ('..')"),
            Component::RootDir | Component::Prefix(_) => return Err("has an absolute path"),
        }
    }
    if out.as_os_str().is_empty() {
        return Err("has an empty name");
    }
    Ok(out)
}

/// Create directory `rel` (and its parents) under `dir`, none of them followed as a link.
fn make_dirs(dir: &Path, rel: &Path) -> io::Result<()> {
    let mut at = dir.to_path_buf();
    for part in rel.components() {
        at.push(part);
        match std::fs::DirBuilder::new().mode(0o700).create(&at) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {
                if !std::fs::symlink_metadata(&at)?.is_dir() {
                    return Err(io::Error::new(e.kind(), "exists and is not a directory"));
                }
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// Check the sizes `archive` (named `label` in errors) declares, every entry's, before anything
/// is unpacked: at most [`MAX_UNPACKED`] bytes together, and no entry of more than
/// [`RATIO_FROM`] bytes unpacking to more than [`MAX_RATIO`] times its compressed size.
pub fn check_sizes<R: io::Read + io::Seek>(
    archive: &mut zip::ZipArchive<R>,
    label: &Path,
) -> Result<(), String> {
    let label = label.display();
    let mut total: u64 = 0;
    for i in 0..archive.len() {
        let entry = archive
            .by_index_raw(i)
            .map_err(|e| format!("{label}: entry {i}: {e}"))?;
        let (name, size, packed) = (entry.name(), entry.size(), entry.compressed_size());
        if size > RATIO_FROM && size / MAX_RATIO > packed {
            return Err(format!(
                "{label}: entry '{name}' unpacks to {size} bytes from {packed} ({}:1, more than the {MAX_RATIO}:1 allowed; a zip bomb?): refused",
                size / packed.max(1)
            ));
        }
        total = total.saturating_add(size);
        if total > MAX_UNPACKED {
            return Err(format!(
                "{label}: entry '{name}' brings the archive's unpacked size to more than {} MiB, the limit: refused",
                MAX_UNPACKED >> 20
            ));
        }
    }
    Ok(())
}

/// Unpack the entries of `archive` (named `label` in errors) whose names pass `keep` into
/// `dir`, a fresh directory of ours, after [`check_sizes`]. Errors are one line naming the
/// archive and the entry; on an error, what was written stays in `dir` for the caller to
/// remove with it.
pub fn unpack<R: io::Read + io::Seek>(
    archive: &mut zip::ZipArchive<R>,
    label: &Path,
    dir: &Path,
    keep: impl Fn(&str) -> bool,
) -> Result<(), String> {
    check_sizes(archive, label)?;
    let label = label.display();
    for i in 0..archive.len() {
        let mut entry = archive
            .by_index(i)
            .map_err(|e| format!("{label}: entry {i}: {e}"))?;
        let name = entry.name().to_owned();
        if !keep(&name) {
            continue;
        }
        let refuse = |why: &str| format!("{label}: entry '{name}' {why}: refused");
        if let Some(kind) = entry.unix_mode().and_then(special) {
            return Err(refuse(&format!("is {kind}")));
        }
        let rel = relative(&name).map_err(refuse)?;
        let out = dir.join(&rel);
        let failed = |e: io::Error| format!("{label}: entry '{name}': {}: {e}", out.display());
        if entry.is_dir() {
            make_dirs(dir, &rel).map_err(failed)?;
            continue;
        }
        if let Some(parent) = rel.parent() {
            make_dirs(dir, parent).map_err(failed)?;
        }
        let executable = entry.unix_mode().is_some_and(|m| m & 0o111 != 0);
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(if executable { 0o700 } else { 0o600 })
            .custom_flags(libc::O_NOFOLLOW)
            .open(&out)
            .map_err(|e| {
                if e.kind() == io::ErrorKind::AlreadyExists {
                    refuse("appears twice (or clashes with a directory)")
                } else {
                    failed(e)
                }
            })?;
        // The declared size was checked; the data may inflate to more than it says. One byte
        // past it is enough to know.
        let declared = entry.size();
        let written = io::copy(&mut (&mut entry).take(declared + 1), &mut file).map_err(failed)?;
        if written > declared {
            return Err(refuse(&format!(
                "holds more than the {declared} bytes it declares"
            )));
        }
    }
    Ok(())
}

/// What a file that is not a regular file is, in words.
fn kind_of(t: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_fifo() {
        "a named pipe"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else if t.is_dir() {
        "a directory"
    } else {
        "not a regular file"
    }
}

/// Open `path` for reading only if it is a regular file. The open does not wait (`O_NONBLOCK`:
/// a named pipe without a writer would block it for ever, deaf to signals), and what it opened
/// is checked (`fstat`) before a byte is read: a pipe, a device, a socket or a directory is
/// refused with an error saying which it is ("not a regular file: a named pipe").
pub fn open_regular(path: &Path) -> io::Result<std::fs::File> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    let kind = file.metadata()?.file_type();
    if !kind.is_file() {
        let what = kind_of(kind);
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            if what == "not a regular file" {
                what.to_owned()
            } else {
                format!("not a regular file: {what}")
            },
        ));
    }
    // A regular file reads the same either way; blocking reads are what the readers expect.
    // SAFETY: fcntl on a descriptor we own, with integer arguments only.
    unsafe {
        use std::os::unix::io::AsRawFd;
        let fd = file.as_raw_fd();
        let flags = libc::fcntl(fd, libc::F_GETFL);
        if flags >= 0 {
            libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK);
        }
    }
    Ok(file)
}

/// The text of the package file `path`: a regular file of at most [`MAX_FILE`] bytes, valid
/// UTF-8. A pipe or device is refused without being read (opening does not wait for a writer).
pub fn read_text(path: &Path) -> io::Result<String> {
    let file = open_regular(path)?;
    let meta = file.metadata()?;
    if meta.len() > MAX_FILE {
        return Err(too_large());
    }
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(MAX_FILE + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_FILE {
        return Err(too_large());
    }
    String::from_utf8(bytes)
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidData, "not valid UTF-8 text"))
}

fn too_large() -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("larger than {} MiB, the reader's limit", MAX_FILE >> 20),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_leave_the_directory_have_no_relative_path() {
        assert_eq!(relative("a/b.txt").unwrap(), Path::new("a/b.txt"));
        assert_eq!(relative("./a").unwrap(), Path::new("a"));
        for bad in [
            "../x",
            "a/../../x",
            "a/..",
            "/etc/passwd",
            "C:/x",
            "a\\..\\x",
            "",
        ] {
            assert!(relative(bad).is_err(), "{bad}");
        }
    }

    /// Archives whose entries declare 600 MiB each (sizes set in the central directory by
    /// hand): one passes, two together exceed [`MAX_UNPACKED`] and are refused, naming the
    /// entry that crosses the limit, before anything is read.
    #[test]
    fn the_declared_total_is_bounded() {
        let archive = |entries: &[&str]| {
            let mut w = zip::ZipWriter::new(io::Cursor::new(Vec::new()));
            for name in entries {
                let stored = zip::write::SimpleFileOptions::default()
                    .compression_method(zip::CompressionMethod::Stored);
                w.start_file(*name, stored).unwrap();
                io::Write::write_all(&mut w, b"x").unwrap();
            }
            let mut bytes = w.finish().unwrap().into_inner();
            let size = (600u32 << 20).to_le_bytes();
            for at in 0..bytes.len() - 4 {
                if bytes[at..at + 4] == [0x50, 0x4b, 0x01, 0x02] {
                    // Compressed and uncompressed size (stored: equal).
                    bytes[at + 20..at + 24].copy_from_slice(&size);
                    bytes[at + 24..at + 28].copy_from_slice(&size);
                }
            }
            zip::ZipArchive::new(io::Cursor::new(bytes)).unwrap()
        };
        let label = Path::new("big.fmu");
        check_sizes(&mut archive(&["a.bin"]), label).unwrap();
        let e = check_sizes(&mut archive(&["a.bin", "b.bin"]), label).unwrap_err();
        assert!(
            e.starts_with("big.fmu: entry 'b.bin'")
                && e.contains("1024 MiB")
                && e.ends_with("refused"),
            "{e}"
        );
    }

    #[test]
    fn special_files_are_named() {
        assert_eq!(special(0o120777), Some("a symbolic link"));
        assert_eq!(special(0o020644), Some("a character device"));
        assert_eq!(special(0o100644), None);
        assert_eq!(special(0o040755), None);
    }
}
