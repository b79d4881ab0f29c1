//! Malformed variants of an SSP system's SSD (a fixed list and seeded random ones), a seeded PRNG, and running `cosim` on one with a timeout: shared by the mutation test and `cargo xtask fuzz`.

use std::io::Read;
use std::path::Path;
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// splitmix64: a small seeded generator, the same sequence on every platform.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    /// The generator of case `index` of a run seeded with `seed` (independent of the others).
    pub fn for_case(seed: u64, index: u64) -> Rng {
        let mut r = Rng(seed ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03));
        r.next_u64();
        r
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n` > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 <= p
    }

    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// A variant of a system's SSD.
#[derive(Debug, Clone)]
pub struct Mutant {
    /// What was changed, e.g. "namespace URI".
    pub class: &'static str,
    pub ssd: String,
    /// The variant is invalid: the master must refuse it (otherwise it may also run).
    pub must_refuse: bool,
}

impl Mutant {
    fn new(class: &'static str, ssd: String, must_refuse: bool) -> Mutant {
        Mutant {
            class,
            ssd,
            must_refuse,
        }
    }
}

/// Unpack the `.ssp` archive into `dir`; returns its SSD text.
pub fn unpack(ssp: &Path, dir: &Path) -> Result<String, String> {
    let file = std::fs::File::open(ssp).map_err(|e| format!("{}: {e}", ssp.display()))?;
    let mut archive = zip::ZipArchive::new(file).map_err(|e| format!("{}: {e}", ssp.display()))?;
    archive
        .extract(dir)
        .map_err(|e| format!("{}: {e}", ssp.display()))?;
    let mut ssd = String::new();
    let path = dir.join("SystemStructure.ssd");
    std::fs::File::open(&path)
        .and_then(|mut f| f.read_to_string(&mut ssd))
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(ssd)
}

/// Every `attr="…"` value occurrence in `ssd` replaced one at a time by `value`.
pub fn each_value(ssd: &str, attr: &str, value: &str) -> Vec<String> {
    let needle = format!("{attr}=\"");
    ssd.match_indices(&needle)
        .filter_map(|(at, _)| {
            let from = at + needle.len();
            let to = from + ssd[from..].find('"')?;
            Some(format!("{}{value}{}", &ssd[..from], &ssd[to..]))
        })
        .collect()
}

/// The value binding of parameter `name` replaced by `element` (e.g. `<ssv:Integer value="…"/>`).
pub fn with_binding(ssd: &str, name: &str, element: &str) -> Option<String> {
    let at = ssd.find(&format!("<ssv:Parameter name=\"{name}\">"))?;
    let from = at + ssd[at..].find("<ssv:")?.max(1);
    let from = from + ssd[from + 1..].find("<ssv:")? + 1;
    let to = from + ssd[from..].find("/>")? + 2;
    Some(format!("{}{element}{}", &ssd[..from], &ssd[to..]))
}

/// The fixed list of malformed variants of `ssd` (a bundled scenario's, with the DER parameters
/// `mode` and `qpi.kp` bound), each invalid unless marked otherwise.
pub fn fixed(ssd: &str) -> Vec<Mutant> {
    let mut mutants = Vec::new();
    let ns = [
        "http://ssp-standard.org/SSP1/SystemStructureDescription",
        "http://ssp-standard.org/SSP1/SystemStructureCommon",
        "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    ];
    for uri in ns {
        for wrong in [format!("{uri}/"), uri.to_uppercase(), "urn:vendor:x".into()] {
            mutants.push(Mutant::new("namespace URI", ssd.replace(uri, &wrong), true));
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
    if let Some(connection) = element(ssd, "<ssd:Connection ") {
        mutants.push(Mutant::new(
            "foreign element",
            declare(&ssd.replacen(
                connection,
                &connection.replace("ssd:Connection", "osp:Connection"),
                1,
            )),
            true,
        ));
    }
    if let Some(connector) = element(ssd, "<ssd:Connector ") {
        mutants.push(Mutant::new(
            "foreign element",
            declare(&ssd.replacen(
                connector,
                &connector.replace("ssd:Connector", "osp:Connector"),
                1,
            )),
            true,
        ));
    }
    mutants.push(Mutant::new(
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
        mutants.push(Mutant::new(
            "lost '<'",
            ssd.replacen(tag, &tag[1..], 1),
            true,
        ));
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
        if let Some(m) = with_binding(ssd, "mode", &format!("<ssv:Integer value=\"{v}\"/>")) {
            mutants.push(Mutant::new("Integer binding", m, true));
        }
    }
    for v in ["NaN", "INF", "-INF", "1e999", "0x10", "1,5"] {
        if let Some(m) = with_binding(ssd, "qpi.kp", &format!("<ssv:Real value=\"{v}\"/>")) {
            mutants.push(Mutant::new("Real binding", m, true));
        }
    }
    // Subnormal values an FMU cannot realize (1/H overflows): refused by name, not a panic.
    for v in ["4.9e-324", "-2e-310", "1e-308"] {
        if let Some(m) = with_binding(ssd, "Tdes.H", &format!("<ssv:Real value=\"{v}\"/>")) {
            mutants.push(Mutant::new("subnormal parameter", m, true));
        }
    }
    // A connection written through a DTD entity (a reader that skips entities never sees it),
    // repeated connector blocks (duplicate CSV columns) and a repeated default experiment.
    if let Some(connection) = element(ssd, "<ssd:Connection ") {
        mutants.push(Mutant::new(
            "DTD entity",
            ssd.replacen(
                "?>",
                &format!(
                    "?>\n<!DOCTYPE ssd:SystemStructureDescription [<!ENTITY c '{}'>]>",
                    connection.replace('"', "&quot;")
                ),
                1,
            )
            .replacen(connection, "&c;", 1),
            true,
        ));
    }
    if let Some(at) = ssd.find("<ssd:Connectors>") {
        if let Some(len) = ssd[at..].find("</ssd:Connectors>") {
            let connectors = &ssd[at..at + len + 17];
            mutants.push(Mutant::new(
                "repeated connectors",
                ssd.replacen(connectors, &connectors.repeat(2), 1),
                true,
            ));
        }
    }
    if let Some(at) = ssd.find("<ssd:DefaultExperiment") {
        if let Some(len) = ssd[at..].find("</ssd:DefaultExperiment>") {
            let experiment = &ssd[at..at + len + 24];
            mutants.push(Mutant::new(
                "repeated experiment",
                ssd.replacen(experiment, &experiment.repeat(2), 1),
                true,
            ));
        }
    }
    // A Boolean, a String or an Enumeration bound to a Real.
    for element in [
        "<ssv:Boolean value=\"true\"/>",
        "<ssv:String value=\"x\"/>",
        "<ssv:Enumeration value=\"x\"/>",
    ] {
        if let Some(m) = with_binding(ssd, "qpi.kp", element) {
            mutants.push(Mutant::new("Real binding", m, true));
        }
    }
    mutants.push(Mutant::new(
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
        for m in each_value(ssd, "startTime", v) {
            mutants.push(Mutant::new("experiment time", m, true));
        }
    }
    for v in ["INF", "NaN", "-1", "0"] {
        for m in each_value(ssd, "stopTime", v) {
            mutants.push(Mutant::new("experiment time", m, true));
        }
    }
    for v in ["0", "-0.001", "NaN", "INF", "1e-12", "1e12"] {
        for m in each_value(ssd, "baseStepSize", v) {
            mutants.push(Mutant::new("experiment time", m, true));
        }
    }
    // Nesting: a vendor annotation deeper than the reader's limit; a document of 200k levels.
    let deep = |n: usize| format!("{}{}", "<v:x>".repeat(n), "</v:x>".repeat(n));
    mutants.push(Mutant::new(
        "nesting",
        ssd.replacen(
            "</ssd:SystemStructureDescription>",
            &format!("<ssd:Annotations><ssc:Annotation type=\"vendor\"><v:r xmlns:v=\"urn:v\">{}</v:r></ssc:Annotation></ssd:Annotations></ssd:SystemStructureDescription>", deep(65_534)),
            1,
        ),
        true,
    ));
    mutants.push(Mutant::new(
        "nesting",
        format!("<a>{}</a>", "<a>".repeat(200_000)),
        true,
    ));
    // Required attributes removed, the document cut short.
    for attr in ["startElement", "endConnector", "kind", "source"] {
        mutants.push(Mutant::new(
            "missing attribute",
            ssd.replacen(&format!(" {attr}=\""), " x=\"", 1),
            true,
        ));
    }
    for cut in [ssd.len() / 3, ssd.len() / 2, ssd.len() - 10] {
        mutants.push(Mutant::new("truncated", cut_at(ssd, cut).to_owned(), true));
    }
    mutants
}

/// `ssd` up to byte `at` (moved back to a character boundary).
fn cut_at(ssd: &str, at: usize) -> &str {
    let at = (0..=at.min(ssd.len()))
        .rev()
        .find(|&i| ssd.is_char_boundary(i))
        .unwrap_or(0);
    &ssd[..at]
}

/// The first element of `ssd` starting with `open` (e.g. `<ssd:Connection `), empty or with
/// content, as text.
fn element<'a>(ssd: &'a str, open: &str) -> Option<&'a str> {
    let at = ssd.find(open)?;
    Some(&ssd[at..at + element_len(&ssd[at..])?])
}

/// The length of the element `text` starts with (its start tag up to the matching end tag; no
/// nesting of the same name, as in an SSD).
fn element_len(text: &str) -> Option<usize> {
    let name_end = text[1..].find(|c: char| c.is_whitespace() || c == '>' || c == '/')? + 1;
    let name = &text[1..name_end];
    let tag_end = text.find('>')?;
    if text[..tag_end].ends_with('/') {
        return Some(tag_end + 1);
    }
    let close = format!("</{name}>");
    Some(text.find(&close)? + close.len())
}

/// Start offsets of every element of `ssd` whose start tag begins with `open`.
fn starts(ssd: &str, open: &str) -> Vec<usize> {
    ssd.match_indices(open).map(|(i, _)| i).collect()
}

/// Values a random attribute mutation writes: empty, non-finite, out of range, denormal, paths
/// outside the package, devices, markup, long.
const VALUES: [&str; 24] = [
    "",
    "NaN",
    "nan",
    "INF",
    "-inf",
    "-1",
    "0",
    "1e308",
    "-1e308",
    "4.9e-324",
    "2.2e-308",
    "1e-310",
    "9007199254740993",
    "x",
    " 1",
    "1 ",
    "../../../etc/passwd",
    "/dev/zero",
    "file:///dev/zero",
    "resources/../resources/grid.fmu",
    "&amp;",
    "&#0;",
    "\u{202e}grid",
    "true",
];

/// Elements a random duplication copies, whether a second copy makes the system invalid (a
/// second component or connector of the same name, a second connector list or experiment; a
/// parameter bound twice to the same value and a connection made twice are accepted), and the
/// class of the variant.
const DUPLICATED: [(&str, bool, &str); 6] = [
    ("<ssd:Component ", true, "repeated Component"),
    ("<ssd:Connectors>", true, "repeated Connectors"),
    ("<ssd:Connector ", true, "repeated Connector"),
    ("<ssv:Parameter ", false, "repeated Parameter"),
    ("<ssd:Connection ", false, "repeated Connection"),
    ("<ssd:DefaultExperiment", true, "repeated DefaultExperiment"),
];

/// A seeded random variant of `ssd`: one of the fixed variants,
/// an attribute value replaced, an element removed or repeated, a character replaced, the text
/// cut short, a DTD with entities, a parameter binding to a file outside the package, or a
/// denormal Real binding.
pub fn random(ssd: &str, fixed: &[Mutant], rng: &mut Rng) -> Mutant {
    match rng.below(10) {
        0 => rng.pick(fixed).clone(),
        1 | 2 => {
            let attrs: Vec<usize> = ssd.match_indices("=\"").map(|(i, _)| i + 2).collect();
            let from = *rng.pick(&attrs);
            let to = from + ssd[from..].find('"').unwrap_or(0);
            let value = if rng.chance(0.1) {
                "9".repeat(1 + rng.below(5000))
            } else {
                rng.pick(&VALUES).to_string()
            };
            Mutant::new(
                "attribute value",
                format!("{}{value}{}", &ssd[..from], &ssd[to..]),
                false,
            )
        }
        3 => {
            let opens = ["<ssd:", "<ssc:", "<ssv:", "<osp:"];
            let all: Vec<usize> = opens.iter().flat_map(|o| starts(ssd, o)).collect();
            let at = *rng.pick(&all);
            match element_len(&ssd[at..]) {
                Some(len) => Mutant::new(
                    "element removed",
                    format!("{}{}", &ssd[..at], &ssd[at + len..]),
                    false,
                ),
                None => Mutant::new("element removed", ssd.to_owned(), false),
            }
        }
        4 => {
            let (open, invalid, class) = *rng.pick(&DUPLICATED);
            let all = starts(ssd, open);
            if all.is_empty() {
                return Mutant::new(class, ssd.to_owned(), false);
            }
            let at = *rng.pick(&all);
            let len = element_len(&ssd[at..]).unwrap_or(0);
            let copy = &ssd[at..at + len];
            Mutant::new(
                class,
                format!("{}{copy}{}", &ssd[..at + len], &ssd[at + len..]),
                invalid && len > 0,
            )
        }
        5 => {
            let at = rng.below(ssd.len());
            let at = (0..=at)
                .rev()
                .find(|&i| ssd.is_char_boundary(i))
                .unwrap_or(0);
            let end = at + ssd[at..].chars().next().map_or(0, char::len_utf8);
            let with = *rng.pick(&[
                "<", ">", "&", "\"", "'", "/", "\0", " ", "=", "\u{feff}", "é",
            ]);
            Mutant::new(
                "character replaced",
                format!("{}{with}{}", &ssd[..at], &ssd[end..]),
                false,
            )
        }
        6 => {
            let root_end = ssd
                .rfind("</ssd:SystemStructureDescription>")
                .unwrap_or(ssd.len());
            let cut = rng.below(root_end.max(1));
            Mutant::new("truncated", cut_at(ssd, cut).to_owned(), true)
        }
        7 => {
            // A DTD, with an internal entity used in an attribute or not used; a DTD is refused.
            let used = rng.chance(0.5);
            let entity = if rng.chance(0.5) {
                "<!ENTITY e \"case\">".to_owned()
            } else {
                // Billion laughs, a few levels.
                let mut s = String::from("<!ENTITY a0 \"lol\">");
                for k in 1..8 {
                    let refs = format!("&a{};", k - 1).repeat(10);
                    s.push_str(&format!("<!ENTITY a{k} \"{refs}\">"));
                }
                s.push_str("<!ENTITY e \"&a7;\">");
                s
            };
            let body = if used {
                ssd.replacen(" description=\"", " description=\"&e;", 1)
            } else {
                ssd.to_owned()
            };
            let at = body.find("?>").map_or(0, |i| i + 2);
            Mutant::new(
                if used {
                    "DTD, entity used"
                } else {
                    "DTD, entity unused"
                },
                format!(
                    "{}<!DOCTYPE ssd:SystemStructureDescription [{entity}]>{}",
                    &body[..at],
                    &body[at..]
                ),
                true,
            )
        }
        8 => {
            // A system-level parameter binding to a file that is not a parameter set of the
            // package: a device, a missing file, a directory, a path out of the package.
            let source = *rng.pick(&[
                "/dev/zero",
                "/dev/urandom",
                "missing.ssv",
                "resources",
                "../../SystemStructure.ssv",
                "/proc/self/mem",
            ]);
            let binding = format!(
                "<ssd:ParameterBindings><ssd:ParameterBinding source=\"{source}\"/></ssd:ParameterBindings>"
            );
            let at = ssd.find("<ssd:Elements>").unwrap_or(0);
            Mutant::new(
                "parameter file",
                format!("{}{binding}{}", &ssd[..at], &ssd[at..]),
                true,
            )
        }
        _ => {
            // A Real binding with a denormal, extreme or negative-zero value.
            let reals: Vec<usize> = starts(ssd, "<ssv:Real value=\"");
            if reals.is_empty() {
                return Mutant::new("Real value", ssd.to_owned(), false);
            }
            let from = *rng.pick(&reals) + "<ssv:Real value=\"".len();
            let to = from + ssd[from..].find('"').unwrap_or(0);
            let value = *rng.pick(&[
                "4.9e-324",
                "-4.9e-324",
                "2.2250738585072009e-308",
                "1e-320",
                "-0",
                "1.7976931348623157e308",
                "-1.7976931348623157e308",
            ]);
            Mutant::new(
                "Real value",
                format!("{}{value}{}", &ssd[..from], &ssd[to..]),
                false,
            )
        }
    }
}

/// How a child process ended.
#[derive(Debug)]
pub enum Exit {
    /// Exited with this code.
    Code(i32),
    /// Killed by this signal.
    Signal(i32),
    /// Still running at the timeout (then killed).
    TimedOut,
}

/// What a child process did: how it ended and its stderr.
#[derive(Debug)]
pub struct Ran {
    pub exit: Exit,
    pub stderr: String,
    pub seconds: f64,
}

/// Run `cmd` (stdout discarded) until it ends or `timeout` passes (then kill it).
pub fn run_with_timeout(cmd: &mut Command, timeout: Duration) -> Result<Ran, String> {
    use std::os::unix::process::ExitStatusExt;
    let started = Instant::now();
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot run {cmd:?}: {e}"))?;
    // Read stderr on a thread, so that a chatty child cannot block on a full pipe.
    let mut pipe = child.stderr.take().expect("stderr is piped");
    let reader = std::thread::spawn(move || {
        let mut bytes = Vec::new();
        let _ = (&mut pipe).take(1 << 20).read_to_end(&mut bytes);
        let _ = std::io::copy(&mut pipe, &mut std::io::sink());
        String::from_utf8_lossy(&bytes).into_owned()
    });
    let status: Option<ExitStatus> = loop {
        match child.try_wait().map_err(|e| e.to_string())? {
            Some(s) => break Some(s),
            None if started.elapsed() >= timeout => {
                let _ = child.kill();
                let _ = child.wait();
                break None;
            }
            None => std::thread::sleep(Duration::from_millis(2)),
        }
    };
    let stderr = reader.join().unwrap_or_default();
    let exit = match status {
        None => Exit::TimedOut,
        Some(s) => match (s.code(), s.signal()) {
            (Some(c), _) => Exit::Code(c),
            (None, Some(sig)) => Exit::Signal(sig),
            (None, None) => Exit::Code(-1),
        },
    };
    Ok(Ran {
        exit,
        stderr,
        seconds: started.elapsed().as_secs_f64(),
    })
}
