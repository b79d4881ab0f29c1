//! A trace of the calls a master makes to one FMU instance, as text, so that the instance can be
//! replayed alone in another tool (`cosim --trace DIR`; `tests/wine/master.c replay`).
//!
//! # Format (version 1)
//!
//! One call per line, in the order the master made them, words separated by one space. The first
//! line is `fmi2-trace 1`; lines starting with `#` are comments. Reals are the 16 hex digits of
//! their IEEE 754 bits (so the replay passes the same bits); strings are percent-encoded (every
//! byte up to space, `%`, `-` and DEL as `%XX`; the empty string is `-`). Header lines, once,
//! before the first call:
//!
//! ```text
//! unit NAME            the component (SSD name)
//! source PATH          the FMU as the SSD names it
//! model ID             its modelIdentifier
//! guid GUID            its guid
//! ```
//!
//! Calls (`N` counts the pairs or references that follow):
//!
//! ```text
//! instantiate NAME TYPE GUID RESOURCE_URI    fmi2Instantiate (TYPE 1: co-simulation)
//! setup_experiment TOLDEF TOL START STOPDEF STOP
//! set_real N VR HEX ...        set_integer N VR I ...      set_boolean N VR 0|1 ...
//! set_string N VR STR ...
//! enter_initialization_mode    exit_initialization_mode    terminate    reset
//! do_step T H NOSET            fmi2DoStep(t, h, noSetFMUStatePriorToCurrentPoint)
//! get_real N VR ...            get_integer N VR ...        get_boolean N VR ...
//! get_string N VR ...          reads (the outputs as the master saw them at this point)
//! get_fmu_state                fmi2GetFMUstate into the instance's one saved state (made by
//!                              the first call, overwritten by the next)
//! set_fmu_state                fmi2SetFMUstate from it      free_fmu_state
//! sample T                     the master recorded a communication point at T with the values
//!                              of its last reads (no FMI call)
//! unsupported CALL             a call this format cannot replay (the replay refuses the trace)
//! ```
//!
//! Logging (`fmi2SetDebugLogging`), the status queries and `fmi2FreeInstance` are not recorded.

use std::fmt::Write as _;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// The first line of every trace.
pub const MAGIC: &str = "fmi2-trace 1";

/// The calls to one instance, written as they are made. Write errors are kept (the first one)
/// and reported by [`Trace::finish`], so a call into the FMU never fails because of its trace.
pub struct Trace {
    out: Box<dyn Write + Send>,
    /// What the trace is written to, for messages.
    name: String,
    error: Option<io::Error>,
    line: String,
}

/// The 16 hex digits of `v`'s bits.
pub fn hex(v: f64) -> String {
    format!("{:016x}", v.to_bits())
}

/// The real whose bits `s` gives (16 hex digits).
pub fn unhex(s: &str) -> Option<f64> {
    (s.len() == 16)
        .then(|| u64::from_str_radix(s, 16).ok())
        .flatten()
        .map(f64::from_bits)
}

/// `s` as one word of a trace (see the module's documentation).
pub fn encode(s: &str) -> String {
    if s.is_empty() {
        return "-".into();
    }
    let mut out = Vec::with_capacity(s.len());
    for &b in s.as_bytes() {
        if b <= b' ' || b == b'%' || b == b'-' || b == 0x7f {
            out.extend_from_slice(format!("%{b:02X}").as_bytes());
        } else {
            // The bytes of multi-byte characters are kept: the text stays UTF-8.
            out.push(b);
        }
    }
    String::from_utf8(out).expect("UTF-8 with ASCII bytes escaped is UTF-8")
}

/// The string one word of a trace stands for (the inverse of [`encode`]).
pub fn decode(word: &str) -> Result<String, String> {
    if word == "-" {
        return Ok(String::new());
    }
    let b = word.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let h = word
                .get(i + 1..i + 3)
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("{word:?}: % not followed by two hex digits"))?;
            out.push(h);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("{word:?}: not UTF-8"))
}

impl Trace {
    /// Create the trace file `path` and write its header (`unit`, `source`, `model`, `guid`).
    pub fn create(path: &Path, header: &[(&str, &str)]) -> io::Result<Trace> {
        let file = File::create(path)?;
        let mut t = Trace::to_writer(
            Box::new(BufWriter::with_capacity(1 << 16, file)),
            path.display().to_string(),
        );
        t.header(header);
        match t.error.take() {
            Some(e) => Err(e),
            None => Ok(t),
        }
    }

    /// A trace written to `out` (named `name` in messages), its first line written.
    pub fn to_writer(out: Box<dyn Write + Send>, name: String) -> Trace {
        let mut t = Trace {
            out,
            name,
            error: None,
            line: String::with_capacity(256),
        };
        t.line.push_str(MAGIC);
        t.end();
        t
    }

    /// Header lines `key value` (values encoded), and a comment saying what the file is.
    pub fn header(&mut self, fields: &[(&str, &str)]) {
        self.line
            .push_str("# the calls of a master to one FMU instance, in order (docs/usage.md)");
        self.end();
        for (k, v) in fields {
            self.line.push_str(k);
            self.line.push(' ');
            self.line.push_str(&encode(v));
            self.end();
        }
    }

    /// Write the line built so far.
    fn end(&mut self) {
        self.line.push('\n');
        if self.error.is_none() {
            if let Err(e) = self.out.write_all(self.line.as_bytes()) {
                self.error = Some(e);
            }
        }
        self.line.clear();
    }

    fn word(&mut self, w: impl std::fmt::Display) {
        let _ = write!(self.line, " {w}");
    }

    fn real(&mut self, v: f64) {
        let _ = write!(self.line, " {:016x}", v.to_bits());
    }

    /// A call without arguments (`enter_initialization_mode`, `terminate`, ...).
    pub fn call(&mut self, name: &str) {
        self.line.push_str(name);
        self.end();
    }

    pub fn instantiate(&mut self, name: &str, fmu_type: i32, guid: &str, resources: &str) {
        self.line.push_str("instantiate");
        self.word(encode(name));
        self.word(fmu_type);
        self.word(encode(guid));
        self.word(encode(resources));
        self.end();
    }

    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: Option<f64>) {
        self.line.push_str("setup_experiment");
        self.word(tolerance.is_some() as i32);
        self.real(tolerance.unwrap_or(0.0));
        self.real(start);
        self.word(stop.is_some() as i32);
        self.real(stop.unwrap_or(0.0));
        self.end();
    }

    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) {
        self.line.push_str("set_real");
        self.word(vrs.len());
        for (vr, v) in vrs.iter().zip(values) {
            self.word(vr);
            self.real(*v);
        }
        self.end();
    }

    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) {
        self.line.push_str("set_integer");
        self.word(vrs.len());
        for (vr, v) in vrs.iter().zip(values) {
            self.word(vr);
            self.word(v);
        }
        self.end();
    }

    /// `fmi2SetBoolean` with the `fmi2Boolean` values passed (0 or 1).
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[i32]) {
        self.line.push_str("set_boolean");
        self.word(vrs.len());
        for (vr, v) in vrs.iter().zip(values) {
            self.word(vr);
            self.word(v);
        }
        self.end();
    }

    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) {
        self.line.push_str("set_string");
        self.word(vrs.len());
        for (vr, v) in vrs.iter().zip(values) {
            self.word(vr);
            self.word(encode(v));
        }
        self.end();
    }

    pub fn do_step(&mut self, t: f64, h: f64, no_set_prior: bool) {
        self.line.push_str("do_step");
        self.real(t);
        self.real(h);
        self.word(no_set_prior as i32);
        self.end();
    }

    /// A read: `get_real`, `get_integer`, `get_boolean` or `get_string` of `vrs`.
    pub fn get(&mut self, call: &str, vrs: &[u32]) {
        self.line.push_str(call);
        self.word(vrs.len());
        for vr in vrs {
            self.word(vr);
        }
        self.end();
    }

    /// The master recorded a communication point at `t` with the values it read last.
    pub fn sample(&mut self, t: f64) {
        self.line.push_str("sample");
        self.real(t);
        self.end();
    }

    /// Flush; the first write error, if any, naming the file.
    pub fn finish(&mut self) -> Result<(), String> {
        if self.error.is_none() {
            if let Err(e) = self.out.flush() {
                self.error = Some(e);
            }
        }
        match &self.error {
            Some(e) => Err(format!("trace {}: {e}", self.name)),
            None => Ok(()),
        }
    }
}

/// One line of a trace, read back ([`read`]).
#[derive(Debug, Clone, PartialEq)]
pub enum Call {
    /// A header line: key and value.
    Header(String, String),
    Instantiate {
        name: String,
        fmu_type: i32,
        guid: String,
        resources: String,
    },
    SetupExperiment {
        tolerance: Option<f64>,
        start: f64,
        stop: Option<f64>,
    },
    SetReal(Vec<(u32, f64)>),
    SetInteger(Vec<(u32, i32)>),
    SetBoolean(Vec<(u32, i32)>),
    SetString(Vec<(u32, String)>),
    DoStep {
        t: f64,
        h: f64,
        no_set_prior: bool,
    },
    /// A read: the call's name and its value references.
    Get(String, Vec<u32>),
    Sample(f64),
    /// A call without arguments, or `unsupported CALL`.
    Plain(String),
}

/// Parse a whole trace; errors name the line.
pub fn read(text: &str) -> Result<Vec<Call>, String> {
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, MAGIC)) => {}
        other => {
            return Err(format!(
                "line 1: {:?} where a trace begins with {MAGIC:?}",
                other.map_or("", |l| l.1)
            ))
        }
    }
    let mut calls = Vec::new();
    for (k, line) in lines {
        if line.starts_with('#') || line.is_empty() {
            continue;
        }
        calls.push(parse_line(line).map_err(|e| format!("line {}: {e}: {line:?}", k + 1))?);
    }
    Ok(calls)
}

fn parse_line(line: &str) -> Result<Call, String> {
    let mut w = line.split(' ');
    let name = w.next().unwrap_or_default();
    let mut next = |what: &str| w.next().ok_or_else(|| format!("no {what}"));
    let int = |s: &str| s.parse::<i64>().map_err(|e| format!("{s:?}: {e}"));
    let vr = |s: &str| s.parse::<u32>().map_err(|e| format!("{s:?}: {e}"));
    let real = |s: &str| unhex(s).ok_or_else(|| format!("{s:?}: not 16 hex digits"));
    let call = match name {
        "unit" | "source" | "model" | "guid" => Call::Header(name.into(), decode(next("value")?)?),
        "instantiate" => Call::Instantiate {
            name: decode(next("name")?)?,
            fmu_type: int(next("type")?)? as i32,
            guid: decode(next("guid")?)?,
            resources: decode(next("resource URI")?)?,
        },
        "setup_experiment" => {
            let tol_defined = int(next("toleranceDefined")?)? != 0;
            let tol = real(next("tolerance")?)?;
            let start = real(next("start")?)?;
            let stop_defined = int(next("stopTimeDefined")?)? != 0;
            let stop = real(next("stop")?)?;
            Call::SetupExperiment {
                tolerance: tol_defined.then_some(tol),
                start,
                stop: stop_defined.then_some(stop),
            }
        }
        "set_real" | "set_integer" | "set_boolean" | "set_string" => {
            let n = int(next("count")?)?;
            let mut pairs = Vec::new();
            for _ in 0..n {
                pairs.push((vr(next("value reference")?)?, next("value")?.to_owned()));
            }
            match name {
                "set_real" => Call::SetReal(
                    pairs
                        .iter()
                        .map(|(r, v)| Ok((*r, real(v)?)))
                        .collect::<Result<_, String>>()?,
                ),
                "set_integer" | "set_boolean" => {
                    let p = pairs
                        .iter()
                        .map(|(r, v)| Ok((*r, int(v)? as i32)))
                        .collect::<Result<_, String>>()?;
                    if name == "set_integer" {
                        Call::SetInteger(p)
                    } else {
                        Call::SetBoolean(p)
                    }
                }
                _ => Call::SetString(
                    pairs
                        .iter()
                        .map(|(r, v)| Ok((*r, decode(v)?)))
                        .collect::<Result<_, String>>()?,
                ),
            }
        }
        "do_step" => Call::DoStep {
            t: real(next("t")?)?,
            h: real(next("h")?)?,
            no_set_prior: int(next("noSetFMUStatePriorToCurrentPoint")?)? != 0,
        },
        "get_real" | "get_integer" | "get_boolean" | "get_string" => {
            let n = int(next("count")?)?;
            let vrs = (0..n)
                .map(|_| vr(next("value reference")?))
                .collect::<Result<_, String>>()?;
            Call::Get(name.into(), vrs)
        }
        "sample" => Call::Sample(real(next("time")?)?),
        "enter_initialization_mode"
        | "exit_initialization_mode"
        | "terminate"
        | "reset"
        | "get_fmu_state"
        | "set_fmu_state"
        | "free_fmu_state" => Call::Plain(name.into()),
        "unsupported" => Call::Plain(format!("unsupported {}", next("call")?)),
        _ => return Err(format!("unknown call {name:?}")),
    };
    if let Some(extra) = w.next() {
        return Err(format!("{extra:?} after the call's arguments"));
    }
    Ok(call)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    /// A writer whose bytes the test reads back.
    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);

    impl Write for Shared {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn strings_round_trip_as_one_word() {
        for s in [
            "",
            "-",
            "a b%c",
            "{8c4e810f-3df3}",
            "file:///a%20b",
            "grüß\tdich\n",
            "x-y",
        ] {
            let w = encode(s);
            assert!(!w.is_empty() && !w.contains([' ', '\n', '\t']), "{w:?}");
            assert_eq!(decode(&w).unwrap(), s, "{w:?}");
        }
        assert_eq!(encode("a b"), "a%20b");
        assert_eq!(encode(""), "-");
        assert!(decode("%2").is_err() && decode("%zz").is_err());
    }

    #[test]
    fn every_call_is_written_exactly_and_read_back() {
        let buf = Shared::default();
        let mut t = Trace::to_writer(Box::new(buf.clone()), "test".into());
        t.header(&[("unit", "der 1"), ("guid", "{g}")]);
        t.instantiate("der 1", 1, "{g}", "file:///tmp/a%20b/resources");
        let tiny = f64::from_bits(1); // the smallest subnormal: text in decimal would need care
        t.setup_experiment(None, 0.0, Some(20.0));
        t.set_real(&[3, 7], &[0.1, -tiny]);
        t.set_integer(&[4], &[-2]);
        t.set_boolean(&[5], &[1]);
        t.set_string(&[6], &["a b"]);
        t.call("enter_initialization_mode");
        t.call("exit_initialization_mode");
        t.get("get_real", &[1, 2]);
        t.sample(0.0);
        t.do_step(0.001, 0.001, true);
        t.call("get_fmu_state");
        t.call("set_fmu_state");
        t.call("terminate");
        t.finish().unwrap();
        let text = String::from_utf8(buf.0.lock().unwrap().clone()).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], MAGIC);
        assert!(lines[1].starts_with('#'));
        assert_eq!(lines[2], "unit der%201");
        assert_eq!(
            lines[4],
            "instantiate der%201 1 {g} file:///tmp/a%2520b/resources"
        );
        assert_eq!(
            lines[5],
            "setup_experiment 0 0000000000000000 0000000000000000 1 4034000000000000"
        );
        assert_eq!(lines[6], "set_real 2 3 3fb999999999999a 7 8000000000000001");
        assert_eq!(lines[12], "get_real 2 1 2");
        assert_eq!(lines[14], "do_step 3f50624dd2f1a9fc 3f50624dd2f1a9fc 1");
        let calls = read(&text).unwrap();
        assert_eq!(calls[0], Call::Header("unit".into(), "der 1".into()));
        assert_eq!(
            calls[2],
            Call::Instantiate {
                name: "der 1".into(),
                fmu_type: 1,
                guid: "{g}".into(),
                resources: "file:///tmp/a%20b/resources".into()
            }
        );
        assert_eq!(
            calls[3],
            Call::SetupExperiment {
                tolerance: None,
                start: 0.0,
                stop: Some(20.0)
            }
        );
        let Call::SetReal(p) = &calls[4] else {
            panic!("{:?}", calls[4])
        };
        assert_eq!(p[1].1.to_bits(), (-tiny).to_bits());
        assert_eq!(calls[6], Call::SetBoolean(vec![(5, 1)]));
        assert_eq!(calls[7], Call::SetString(vec![(6, "a b".into())]));
        assert_eq!(calls[10], Call::Get("get_real".into(), vec![1, 2]));
        assert_eq!(calls[11], Call::Sample(0.0));
        assert_eq!(
            calls[12],
            Call::DoStep {
                t: 0.001,
                h: 0.001,
                no_set_prior: true
            }
        );
        assert_eq!(calls[15], Call::Plain("terminate".into()));
    }

    #[test]
    fn bad_lines_are_named() {
        assert!(read("something else\n").unwrap_err().contains("line 1"));
        let e = read("fmi2-trace 1\nset_real 2 3 3fb999999999999a\n").unwrap_err();
        assert!(
            e.contains("line 2") && e.contains("no value reference"),
            "{e}"
        );
        let e = read("fmi2-trace 1\ndo_step 1 2 1\n").unwrap_err();
        assert!(e.contains("not 16 hex digits"), "{e}");
        let e = read("fmi2-trace 1\nterminate now\n").unwrap_err();
        assert!(e.contains("after the call's arguments"), "{e}");
        let e = read("fmi2-trace 1\nfly\n").unwrap_err();
        assert!(e.contains("unknown call"), "{e}");
    }

    #[test]
    fn write_errors_are_kept_and_reported_once() {
        struct Full;
        impl Write for Full {
            fn write(&mut self, _: &[u8]) -> io::Result<usize> {
                Err(io::Error::other("disk full"))
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let mut t = Trace::to_writer(Box::new(Full), "x.trace".into());
        t.do_step(0.0, 1.0, true);
        let e = t.finish().unwrap_err();
        assert!(e.contains("x.trace") && e.contains("disk full"), "{e}");
    }
}
