//! Packages from elsewhere cannot reach outside the directories the master unpacks them into:
//! archive entries that are links, devices or paths leaving the directory are refused, the
//! unpacking directories are fresh and private (a directory planted under a predictable name is
//! never used), and the SSD reader refuses DTDs, repeated connector blocks and parameter files
//! that are not regular files of a bounded size.

use dvpp_cosim::ssp;
use dvpp_cosim::tmp::TempDir;
use dvpp_cosim::Fmu;
use std::io::Write;
use std::path::{Path, PathBuf};

const SSD: &str = r#"<?xml version="1.0"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="t">
  <ssd:System name="sys">
    <ssd:Elements>
      <ssd:Component name="a" source="resources/a.fmu">
        <ssd:Connectors>
          <ssd:Connector name="y" kind="output"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
        PARAMETERS
      </ssd:Component>
      <ssd:Component name="b" source="resources/grid.fmu">
        <ssd:Connectors>
          <ssd:Connector name="u" kind="input"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      CONNECTION
    </ssd:Connections>
  </ssd:System>
</ssd:SystemStructureDescription>
"#;

const CONNECTION: &str =
    r#"<ssd:Connection startElement="a" startConnector="y" endElement="b" endConnector="u"/>"#;

fn ssd(parameters: &str, connection: &str) -> String {
    SSD.replace("PARAMETERS", parameters)
        .replace("CONNECTION", connection)
}

/// One archive entry: name, Unix mode (file type bits included), contents.
type Entry<'a> = (&'a str, u32, &'a [u8]);

fn write_zip(path: &Path, entries: &[Entry]) {
    let mut w = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    for &(name, mode, data) in entries {
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .unix_permissions(mode);
        if mode & 0o170000 == 0o120000 {
            w.add_symlink(name, std::str::from_utf8(data).unwrap(), options)
                .unwrap();
        } else {
            w.start_file(name, options).unwrap();
            w.write_all(data).unwrap();
        }
    }
    w.finish().unwrap();
    // The writer keeps only the permission bits of other modes: devices and pipes are set in
    // the central directory by hand (external attributes, the Unix mode in the upper half).
    let mut bytes = std::fs::read(path).unwrap();
    for &(name, mode, _) in entries {
        let kind = mode & 0o170000;
        if kind == 0o100000 || kind == 0o120000 || kind == 0o040000 {
            continue;
        }
        let at = (0..bytes.len() - 46)
            .find(|&i| {
                bytes[i..i + 4] == [0x50, 0x4b, 0x01, 0x02]
                    && bytes[i + 46..].starts_with(name.as_bytes())
            })
            .expect("the entry's central directory header");
        bytes[at + 38..at + 42].copy_from_slice(&(mode << 16).to_le_bytes());
    }
    std::fs::write(path, bytes).unwrap();
}

/// An error of one line that names `archive` and `entry`.
fn assert_refused(e: &str, archive: &Path, entry: &str) {
    assert!(!e.contains('\n'), "more than one line: {e}");
    assert!(e.contains(&archive.display().to_string()), "{e}");
    assert!(e.contains(&format!("'{entry}'")), "{e}");
    assert!(e.contains("refused"), "{e}");
}

#[test]
fn an_ssp_entry_that_is_a_symbolic_link_is_refused_and_not_followed() {
    let t = TempDir::new("test-ssp-link").unwrap();
    let victim = t.path().join("victim.txt");
    std::fs::write(&victim, "precious").unwrap();
    let ssp = t.path().join("linked.ssp");
    let ssd_text = ssd("", CONNECTION);
    write_zip(
        &ssp,
        &[
            ("SystemStructure.ssd", 0o100644, ssd_text.as_bytes()),
            (
                "resources/grid.fmu",
                0o120777,
                victim.to_str().unwrap().as_bytes(),
            ),
            ("resources/a.fmu", 0o100644, b"not read"),
        ],
    );
    let e = ssp::read(&ssp).unwrap_err().0;
    assert_refused(&e, &ssp, "resources/grid.fmu");
    assert!(e.contains("symbolic link"), "{e}");
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
}

#[test]
fn ssp_entries_leaving_the_directory_or_special_are_refused() {
    let t = TempDir::new("test-ssp-escape").unwrap();
    let outside = t.path().join("outside.txt");
    let ssd_text = ssd("", CONNECTION);
    let escape = format!("../{}", "outside.txt");
    let absolute = outside.to_str().unwrap().to_owned();
    for (entry, mode) in [
        ("resources/../../outside.txt", 0o100644),
        (escape.as_str(), 0o100644),
        (absolute.as_str(), 0o100644),
        ("resources/dev", 0o020644),
        ("resources/pipe", 0o010644),
    ] {
        let ssp = t.path().join("bad.ssp");
        write_zip(
            &ssp,
            &[
                ("SystemStructure.ssd", 0o100644, ssd_text.as_bytes()),
                (entry, mode, b"overwritten"),
            ],
        );
        let e = ssp::read(&ssp).expect_err(entry).0;
        assert_refused(&e, &ssp, entry);
        assert!(!outside.exists(), "{entry} was written outside");
    }
}

#[test]
fn fmu_entries_that_are_links_or_leave_the_directory_are_refused() {
    let t = TempDir::new("test-fmu-escape").unwrap();
    let victim = t.path().join("victim.so");
    std::fs::write(&victim, "precious").unwrap();
    for (entry, mode, data) in [
        ("resources/x.so", 0o120777, victim.to_str().unwrap()),
        ("resources/../../victim.so", 0o100644, "overwritten"),
        ("/tmp/dvpp-absolute-entry", 0o100644, "overwritten"),
        ("resources/tty", 0o020666, ""),
    ] {
        let fmu = t.path().join("bad.fmu");
        write_zip(
            &fmu,
            &[
                ("modelDescription.xml", 0o100644, b"<fmiModelDescription/>"),
                (entry, mode, data.as_bytes()),
            ],
        );
        let e = Fmu::load(&fmu).err().expect("refused").0;
        assert_refused(&e, &fmu, entry);
        assert_eq!(std::fs::read_to_string(&victim).unwrap(), "precious");
        assert!(!Path::new("/tmp/dvpp-absolute-entry").exists());
    }
}

/// The directories a run of the old naming scheme would have unpacked `probe.fmu` into.
fn predictable(stem: &str) -> Vec<PathBuf> {
    (0..64)
        .map(|n| std::env::temp_dir().join(format!("dvpp-cosim-{}-{n}-{stem}", std::process::id())))
        .collect()
}

#[test]
fn a_directory_planted_under_a_predictable_name_is_not_used() {
    let t = TempDir::new("test-planted").unwrap();
    let stem = format!("planted{}", std::process::id());
    let planted = predictable(&stem);
    for p in &planted {
        std::fs::create_dir(p).unwrap();
        std::fs::write(p.join("marker"), "planted").unwrap();
    }
    let fmu = t.path().join(format!("{stem}.fmu"));
    write_zip(
        &fmu,
        &[(
            "modelDescription.xml",
            0o100644,
            b"<fmiModelDescription/>" as &[u8],
        )],
    );
    let e = Fmu::load(&fmu).err().expect("not an FMU").0;
    let untouched = planted.iter().all(|p| {
        std::fs::read_dir(p).map(|d| d.count()).ok() == Some(1)
            && std::fs::read_to_string(p.join("marker")).ok().as_deref() == Some("planted")
    });
    for p in &planted {
        let _ = std::fs::remove_dir_all(p);
    }
    assert!(untouched, "a planted directory was used ({e})");
}

#[test]
fn an_ssp_is_unpacked_into_a_fresh_private_directory() {
    use std::os::unix::fs::PermissionsExt;
    let t = TempDir::new("test-fresh").unwrap();
    let ssp = t.path().join("fresh.ssp");
    let ssd_text = ssd("", CONNECTION);
    write_zip(
        &ssp,
        &[("SystemStructure.ssd", 0o100644, ssd_text.as_bytes())],
    );
    let a = ssp::read(&ssp).unwrap();
    let b = ssp::read(&ssp).unwrap();
    assert_ne!(a.dir, b.dir);
    let meta = std::fs::symlink_metadata(&a.dir).unwrap();
    assert!(meta.is_dir());
    assert_eq!(meta.permissions().mode() & 0o077, 0, "{:?}", a.dir);
    let dir = a.dir.clone();
    drop(a);
    assert!(!dir.exists(), "removed on drop");
}

#[test]
fn a_dtd_and_entity_references_are_refused() {
    // The connection written through an internal entity was dropped silently.
    let through_entity = format!(
        "<!DOCTYPE ssd:SystemStructureDescription [<!ENTITY c '{}'>]>\n{}",
        CONNECTION.replace('"', "&quot;"),
        ssd("", "&c;").replacen("<?xml version=\"1.0\"?>\n", "", 1)
    );
    let e = ssp::parse_ssd(&through_entity, Path::new("."))
        .unwrap_err()
        .0;
    assert!(e.contains("DOCTYPE") && !e.contains('\n'), "{e}");
    // Without the declaration, the reference alone.
    let e = ssp::parse_ssd(&ssd("", "&c;"), Path::new("."))
        .unwrap_err()
        .0;
    assert!(e.contains("&c;") && !e.contains('\n'), "{e}");
    // The plain document is fine.
    let s = ssp::parse_ssd(&ssd("", CONNECTION), Path::new(".")).unwrap();
    assert_eq!(s.connections.len(), 1);
}

#[test]
fn a_repeated_connectors_block_is_refused() {
    let doubled = ssd("", CONNECTION).replacen(
        "</ssd:Connectors>",
        "</ssd:Connectors><ssd:Connectors><ssd:Connector name=\"y\" kind=\"output\"><ssc:Real/></ssd:Connector></ssd:Connectors>",
        1,
    );
    let e = ssp::parse_ssd(&doubled, Path::new(".")).unwrap_err().0;
    assert!(
        e.contains("second <ssd:Connectors>") && e.contains("'a'"),
        "{e}"
    );
    let system = ssd("", CONNECTION).replacen(
        "<ssd:System name=\"sys\">",
        "<ssd:System name=\"sys\"><ssd:Connectors/><ssd:Connectors/>",
        1,
    );
    let e = ssp::parse_ssd(&system, Path::new(".")).unwrap_err().0;
    assert!(
        e.contains("second <ssd:Connectors>") && e.contains("'sys'"),
        "{e}"
    );
}

fn binding(source: &str) -> String {
    format!(
        r#"<ssd:ParameterBindings><ssd:ParameterBinding source="{source}"/></ssd:ParameterBindings>"#
    )
}

#[test]
fn parameter_files_must_be_regular_and_bounded() {
    let t = TempDir::new("test-ssv").unwrap();
    // /dev/zero was read until memory ran out; a named pipe would block.
    let fifo = t.path().join("pipe.ssv");
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: a valid NUL-terminated path.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    for source in ["/dev/zero", "pipe.ssv"] {
        let e = ssp::parse_ssd(&ssd(&binding(source), CONNECTION), t.path())
            .unwrap_err()
            .0;
        assert!(
            e.contains("not a regular file") && e.contains(source),
            "{e}"
        );
    }
    let big = t.path().join("big.ssv");
    let f = std::fs::File::create(&big).unwrap();
    f.set_len(17 << 20).unwrap();
    let e = ssp::parse_ssd(&ssd(&binding("big.ssv"), CONNECTION), t.path())
        .unwrap_err()
        .0;
    assert!(e.contains("16 MiB") && !e.contains('\n'), "{e}");
}

/// Temporary directories of ours whose name holds `stem` (what an unpacking left behind).
fn unpacked_dirs(stem: &str) -> Vec<PathBuf> {
    std::fs::read_dir(std::env::temp_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("dvpp-") && n.contains(stem))
        })
        .collect()
}

/// An archive of `entries` (name, contents), each deflated.
fn write_deflated(path: &Path, entries: &[(&str, &[u8])]) {
    let mut w = zip::ZipWriter::new(std::fs::File::create(path).unwrap());
    for &(name, data) in entries {
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated);
        w.start_file(name, options).unwrap();
        w.write_all(data).unwrap();
    }
    w.finish().unwrap();
}

/// A zip bomb: 10 MB of zeros deflate to about 10 kB (1000:1). Every entry was inflated in
/// full before any check (1 GB written per MB of archive); now the declared sizes are checked
/// first, and the archive is refused with its name and the entry's, nothing unpacked.
#[test]
fn an_entry_that_inflates_far_beyond_its_size_is_refused_before_unpacking() {
    let t = TempDir::new("test-bomb").unwrap();
    let zeros = vec![0u8; 10 << 20];
    let stem = format!("bomb{}", std::process::id());
    let fmu = t.path().join(format!("{stem}.fmu"));
    write_deflated(
        &fmu,
        &[
            ("modelDescription.xml", b"<fmiModelDescription/>"),
            ("resources/zeros.bin", &zeros),
        ],
    );
    let size = std::fs::metadata(&fmu).unwrap().len();
    assert!(size < 100 << 10, "a small archive: {size} bytes");
    let e = Fmu::load(&fmu).err().expect("refused").0;
    assert_refused(&e, &fmu, "resources/zeros.bin");
    assert!(e.contains("100:1"), "the limit is stated: {e}");
    assert!(unpacked_dirs(&stem).is_empty(), "left behind");

    let ssp = t.path().join(format!("{stem}.ssp"));
    let ssd_text = ssd("", CONNECTION);
    write_deflated(
        &ssp,
        &[
            ("SystemStructure.ssd", ssd_text.as_bytes()),
            ("resources/a.fmu", &zeros),
        ],
    );
    let e = ssp::read(&ssp).unwrap_err().0;
    assert_refused(&e, &ssp, "resources/a.fmu");
    assert!(unpacked_dirs(&stem).is_empty(), "left behind");
}

/// The declared size can lie: an entry that holds more than it declares is cut one byte past
/// its declared size and refused (the ratio check alone would pass it).
#[test]
fn an_entry_larger_than_it_declares_is_cut_and_refused() {
    let t = TempDir::new("test-lying-size").unwrap();
    let data = vec![7u8; 2 << 20];
    let fmu = t.path().join("lying.fmu");
    write_zip(
        &fmu,
        &[
            ("modelDescription.xml", 0o100644, b"<fmiModelDescription/>"),
            ("resources/big.bin", 0o100644, &data),
        ],
    );
    // Declare 1000 bytes in the local and the central header (uncompressed size fields).
    let mut bytes = std::fs::read(&fmu).unwrap();
    let name = b"resources/big.bin";
    for (signature, at_size, at_name) in [
        ([0x50, 0x4b, 0x03, 0x04], 22, 30),
        ([0x50, 0x4b, 0x01, 0x02], 24, 46),
    ] {
        let at = (0..bytes.len() - at_name - name.len())
            .find(|&i| bytes[i..i + 4] == signature && bytes[i + at_name..].starts_with(name))
            .expect("the entry's header");
        bytes[at + at_size..at + at_size + 4].copy_from_slice(&1000u32.to_le_bytes());
    }
    std::fs::write(&fmu, bytes).unwrap();
    let e = Fmu::load(&fmu).err().expect("refused").0;
    assert_refused(&e, &fmu, "resources/big.bin");
    assert!(e.contains("more than the 1000 bytes it declares"), "{e}");
}
