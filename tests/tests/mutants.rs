//! Mutation test of the SSP reader and the master: malformed variants of a shipped scenario's
//! SSD and parameter bindings, each run by the `cosim` binary. Every mutant must either run with
//! results identical to the original or be refused with one line; none may panic or die of a
//! signal. The count of each outcome per class of mutation is printed.

use dvpp_e2e::{cosim, scenario};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::Command;

/// What a mutant did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Outcome {
    /// Ran, with results identical to the original system's.
    Unchanged,
    /// Refused (exit 1) with one `cosim:` line naming what is wrong.
    Refused,
    /// Anything else: a panic, a signal, other results, several or no error lines.
    Bad,
}

/// Unpack the scenario's `.ssp` into `dir`; returns its SSD text.
fn unpack(ssp: &Path, dir: &Path) -> String {
    let mut archive =
        zip::ZipArchive::new(std::fs::File::open(ssp).expect("open the .ssp")).expect("a zip");
    archive.extract(dir).expect("unpack");
    let mut ssd = String::new();
    std::fs::File::open(dir.join("SystemStructure.ssd"))
        .expect("the SSD")
        .read_to_string(&mut ssd)
        .expect("read the SSD");
    ssd
}

struct Runner {
    dir: PathBuf,
    baseline: String,
    count: usize,
}

impl Runner {
    /// Run `ssd` (written next to the unpacked FMUs); returns the outcome and what it printed.
    fn run(&mut self, ssd: &str) -> (Outcome, String) {
        self.count += 1;
        let file = self.dir.join("mutant.ssd");
        let out = self.dir.join("mutant.csv");
        let _ = std::fs::remove_file(&out);
        std::fs::write(&file, ssd).expect("write the mutant");
        let done = Command::new(cosim())
            .arg(&file)
            .args(["--stop", "0.02", "--out"])
            .arg(&out)
            .output()
            .expect("run cosim");
        let stderr = String::from_utf8_lossy(&done.stderr).into_owned();
        let errors: Vec<&str> = stderr
            .lines()
            .filter(|l| l.starts_with("cosim: ") && !l.contains("warning"))
            .collect();
        let outcome = match done.status.code() {
            Some(0) if std::fs::read_to_string(&out).ok().as_deref() == Some(&self.baseline) => {
                Outcome::Unchanged
            }
            Some(1) if errors.len() == 1 && !stderr.contains("panicked") => Outcome::Refused,
            _ => Outcome::Bad,
        };
        (outcome, stderr)
    }
}

/// Every `attr="…"` value occurrence in `ssd` replaced one at a time by `value`.
fn each_value(ssd: &str, attr: &str, value: &str) -> Vec<String> {
    let needle = format!("{attr}=\"");
    ssd.match_indices(&needle)
        .map(|(at, _)| {
            let from = at + needle.len();
            let to = from + ssd[from..].find('"').expect("a closing quote");
            format!("{}{value}{}", &ssd[..from], &ssd[to..])
        })
        .collect()
}

/// The value binding of parameter `name` replaced by `element` (e.g. `<ssv:Integer value="…"/>`).
fn with_binding(ssd: &str, name: &str, element: &str) -> Option<String> {
    let at = ssd.find(&format!("<ssv:Parameter name=\"{name}\">"))?;
    let from = at + ssd[at..].find("<ssv:")?.max(1);
    let from = from + ssd[from + 1..].find("<ssv:")? + 1;
    let to = from + ssd[from..].find("/>")? + 2;
    Some(format!("{}{element}{}", &ssd[..from], &ssd[to..]))
}

#[test]
fn malformed_systems_are_refused_or_run_unchanged() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mutants");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create the directory");
    let ssd = unpack(&scenario("case1_load"), &dir);
    let mut runner = Runner {
        dir: dir.clone(),
        baseline: String::new(),
        count: 0,
    };
    let (first, stderr) = runner.run(&ssd);
    assert_eq!(
        first,
        Outcome::Bad,
        "the original cannot match an empty baseline"
    );
    runner.baseline = std::fs::read_to_string(dir.join("mutant.csv"))
        .unwrap_or_else(|e| panic!("the original system did not run ({e}): {stderr}"));

    // (class, mutant, must it be refused?)
    let mut mutants: Vec<(&str, String, bool)> = Vec::new();
    let ns = [
        "http://ssp-standard.org/SSP1/SystemStructureDescription",
        "http://ssp-standard.org/SSP1/SystemStructureCommon",
        "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    ];
    for uri in ns {
        for wrong in [format!("{uri}/"), uri.to_uppercase(), "urn:vendor:x".into()] {
            mutants.push(("namespace URI", ssd.replace(uri, &wrong), true));
        }
    }
    // Elements in a foreign namespace where the master would drop them, and inside annotations.
    let osp = "xmlns:osp=\"http://opensimulationplatform.com/SSP/OSPAnnotations\"";
    let declare = |s: &str| {
        if s.contains(osp) {
            s.to_owned()
        } else {
            s.replacen(
                "<ssd:SystemStructureDescription ",
                &format!("<ssd:SystemStructureDescription {osp} "),
                1,
            )
        }
    };
    let connection = {
        let at = ssd.find("<ssd:Connection ").expect("a connection");
        ssd[at..at + ssd[at..].find("/>").expect("an empty element") + 2].to_owned()
    };
    mutants.push((
        "foreign element",
        declare(&ssd.replacen(
            &connection,
            &connection.replace("ssd:Connection", "osp:Connection"),
            1,
        )),
        true,
    ));
    let connector = {
        let at = ssd.find("<ssd:Connector ").expect("a connector");
        ssd[at..at + ssd[at..].find("</ssd:Connector>").expect("an end tag") + 16].to_owned()
    };
    mutants.push((
        "foreign element",
        declare(&ssd.replacen(
            &connector,
            &connector.replace("ssd:Connector", "osp:Connector"),
            1,
        )),
        true,
    ));
    mutants.push((
        "foreign element",
        ssd.replacen(
            "</ssd:SystemStructureDescription>",
            "<ssd:Annotations><ssc:Annotation type=\"vendor\"><v:x xmlns:v=\"urn:v\">free text<v:y/></v:x></ssc:Annotation></ssd:Annotations></ssd:SystemStructureDescription>",
            1,
        ),
        false,
    ));
    // A lost '<' turns an element into text.
    for tag in [
        "<ssd:Connection ",
        "<ssd:Connector ",
        "<ssv:Parameter ",
        "<ssd:Component ",
    ] {
        mutants.push(("lost '<'", ssd.replacen(tag, &tag[1..], 1), true));
    }
    // Integer and Real bindings outside what FMI can hold.
    for v in [
        "4294967298",
        "2147483648",
        "-2147483649",
        "99999999999999999999",
        "1.5",
        "",
    ] {
        if let Some(m) = with_binding(&ssd, "mode", &format!("<ssv:Integer value=\"{v}\"/>")) {
            mutants.push(("Integer binding", m, true));
        }
    }
    for v in ["NaN", "INF", "-INF", "1e999", "0x10", "1,5"] {
        if let Some(m) = with_binding(&ssd, "qpi.kp", &format!("<ssv:Real value=\"{v}\"/>")) {
            mutants.push(("Real binding", m, true));
        }
    }
    for (what, element) in [
        ("a Boolean for a Real", "<ssv:Boolean value=\"true\"/>"),
        ("a String for a Real", "<ssv:String value=\"x\"/>"),
        ("an Enumeration", "<ssv:Enumeration value=\"x\"/>"),
    ] {
        if let Some(m) = with_binding(&ssd, "qpi.kp", element) {
            let _ = what;
            mutants.push(("Real binding", m, true));
        }
    }
    // Subnormal values an FMU cannot realize (1/H overflows): refused by name, not a panic.
    for v in ["4.9e-324", "-2e-310", "1e-308"] {
        if let Some(m) = with_binding(&ssd, "Tdes.H", &format!("<ssv:Real value=\"{v}\"/>")) {
            mutants.push(("subnormal parameter", m, true));
        }
    }
    // A connection written through a DTD entity (the reader never saw it) and repeated
    // connector blocks (duplicate CSV columns).
    mutants.push((
        "DTD entity",
        ssd.replacen(
            "?>",
            &format!(
                "?>\n<!DOCTYPE ssd:SystemStructureDescription [<!ENTITY c '{}'>]>",
                connection.replace('"', "&quot;")
            ),
            1,
        )
        .replacen(&connection, "&c;", 1),
        true,
    ));
    let connectors = {
        let at = ssd.find("<ssd:Connectors>").expect("a connectors block");
        ssd[at..at + ssd[at..].find("</ssd:Connectors>").expect("an end tag") + 17].to_owned()
    };
    mutants.push((
        "repeated connectors",
        ssd.replacen(&connectors, &connectors.repeat(2), 1),
        true,
    ));
    mutants.push((
        "Real binding",
        ssd.replacen(
            "<ssv:Parameter name=\"qpi.kp\">",
            "<ssv:Parameter name=\"qpi.kq\">",
            1,
        ),
        true,
    ));
    // Experiment times: not finite, not positive, or beyond what the master can represent.
    for v in ["-1e9", "-1e10", "-1e308", "NaN", "INF", "1e12", "x"] {
        for m in each_value(&ssd, "startTime", v) {
            mutants.push(("experiment time", m, true));
        }
    }
    for v in ["INF", "NaN", "-1", "0"] {
        for m in each_value(&ssd, "stopTime", v) {
            mutants.push(("experiment time", m, true));
        }
    }
    for v in ["0", "-0.001", "NaN", "INF", "1e-12", "1e12"] {
        for m in each_value(&ssd, "baseStepSize", v) {
            mutants.push(("experiment time", m, true));
        }
    }
    // Nesting: a vendor annotation deeper than the reader's limit; a document of 200k levels.
    let deep = |n: usize| format!("{}{}", "<v:x>".repeat(n), "</v:x>".repeat(n));
    mutants.push((
        "nesting",
        ssd.replacen(
            "</ssd:SystemStructureDescription>",
            &format!("<ssd:Annotations><ssc:Annotation type=\"vendor\"><v:r xmlns:v=\"urn:v\">{}</v:r></ssc:Annotation></ssd:Annotations></ssd:SystemStructureDescription>", deep(65_534)),
            1,
        ),
        true,
    ));
    mutants.push(("nesting", format!("<a>{}</a>", "<a>".repeat(200_000)), true));
    // Required attributes removed, the document cut short.
    for attr in ["startElement", "endConnector", "kind", "source"] {
        mutants.push((
            "missing attribute",
            ssd.replacen(&format!(" {attr}=\""), " x=\"", 1),
            true,
        ));
    }
    for cut in [ssd.len() / 3, ssd.len() / 2, ssd.len() - 10] {
        let cut = (0..=cut)
            .rev()
            .find(|&i| ssd.is_char_boundary(i))
            .unwrap_or(0);
        mutants.push(("truncated", ssd[..cut].to_owned(), true));
    }

    let mut counts: BTreeMap<(&str, Outcome), usize> = BTreeMap::new();
    let mut bad = Vec::new();
    for (class, mutant, must_refuse) in &mutants {
        let (outcome, stderr) = runner.run(mutant);
        *counts.entry((class, outcome)).or_default() += 1;
        if outcome == Outcome::Bad || (*must_refuse && outcome != Outcome::Refused) {
            bad.push(format!("[{class}] {outcome:?}: {}", stderr.trim()));
        } else if outcome == Outcome::Refused {
            eprintln!("[{class}] refused: {}", stderr.lines().last().unwrap_or(""));
        }
    }
    println!("{} mutants:", mutants.len());
    for ((class, outcome), n) in &counts {
        println!("  {class:<20} {outcome:?}: {n}");
    }
    assert!(
        bad.is_empty(),
        "mutants handled wrongly:\n{}",
        bad.join("\n\n")
    );
}
