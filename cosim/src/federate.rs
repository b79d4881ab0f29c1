//! Scaling out: some components of an SSP system run as one HELICS value federate (libhelics loaded at run time), with the results of the Jacobi master bit for bit; and a launcher of a whole federation on one machine.
//!
//! Every federate loads the whole system (for its connections and the units' dependencies) but
//! initializes and steps only its own components. The master's exchange walks the connections in
//! dependency order (a unit's output is read after the inputs it depends on were set); a
//! federation walks the same order, split into *rounds*: a connection between two components is
//! read by its source in some round and set at its destination in a later one (the value goes
//! through HELICS, published as `component.variable`), so every unit sees the calls of the master
//! in the same order with the same values. The schedule of rounds depends on the system only (not
//! on how components are grouped into federates): every federate computes the same one, and
//! HELICS time counts rounds (1 s per round, uninterruptible), not simulated time.
//!
//! Initialization, the exchange, stepping and sampling are the master's coupling core, run over
//! this federate's components: the federate hands it its rounds as the plan of each exchange
//! and is its transport (values between its own components copied, values to and from other
//! federates published and taken in the rounds). What is left here is HELICS's: the library,
//! the federate, its interfaces and its run; the schedule of rounds and grants is in `rounds`,
//! the launcher of a whole federation in `launch`.

use crate::dl::dl_api;
use crate::master::{
    CsvWriter, End, Error, Event, Link, Observer, Options, Phase, Plans, RunInfo, System, Transport,
};
use crate::ssp;
use crate::table::seconds;
use libc::{c_char, c_int, c_void};
use std::collections::BTreeMap;
use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

mod launch;
mod rounds;

pub use launch::{
    groups, run_federation, FederationOptions, FederationReport, Timing, GLOBAL_FROM,
};
use rounds::{packed_slots, schedule};

fn err<T>(msg: impl Into<String>) -> Result<T, Error> {
    Err(Error::Federation(msg.into()))
}

#[repr(C)]
struct HelicsError {
    error_code: i32,
    message: *const c_char,
}

type Handle = *mut c_void;
type E = *mut HelicsError;

dl_api! {
    /// The C functions of libhelics this module calls (signatures of helics.h, HELICS 3).
    "no function {} (HELICS 3 expected)";
    error_initialize: "helicsErrorInitialize" => fn() -> HelicsError;
    get_version: "helicsGetVersion" => fn() -> *const c_char;
    create_federate_info: "helicsCreateFederateInfo" => fn() -> Handle;
    info_core_type: "helicsFederateInfoSetCoreTypeFromString" => fn(Handle, *const c_char, E);
    info_core_init: "helicsFederateInfoSetCoreInitString" => fn(Handle, *const c_char, E);
    info_flag: "helicsFederateInfoSetFlagOption" => fn(Handle, c_int, c_int, E);
    info_free: "helicsFederateInfoFree" => fn(Handle);
    create_value_federate: "helicsCreateValueFederate" => fn(*const c_char, Handle, E) -> Handle;
    register_global_publication: "helicsFederateRegisterGlobalPublication" => fn(Handle, *const c_char, c_int, *const c_char, E) -> Handle;
    register_subscription: "helicsFederateRegisterSubscription" => fn(Handle, *const c_char, *const c_char, E) -> Handle;
    publish_double: "helicsPublicationPublishDouble" => fn(Handle, f64, E);
    publish_vector: "helicsPublicationPublishVector" => fn(Handle, *const f64, c_int, E);
    input_get_double: "helicsInputGetDouble" => fn(Handle, E) -> f64;
    input_get_vector: "helicsInputGetVector" => fn(Handle, *mut f64, c_int, *mut c_int, E);
    enter_executing_mode: "helicsFederateEnterExecutingMode" => fn(Handle, E);
    request_time: "helicsFederateRequestTime" => fn(Handle, f64, E) -> f64;
    finalize: "helicsFederateFinalize" => fn(Handle, E);
    federate_free: "helicsFederateFree" => fn(Handle);
    close_library: "helicsCloseLibrary" => fn();
}

/// libhelics, dlopened (`helicsCloseLibrary` on drop; never unmapped).
pub struct Helics {
    api: Api,
    path: PathBuf,
}

/// The HELICS core type federates and brokers use unless told otherwise: TCP over a single
/// socket, so that only the broker listens (on one port) and the federates only connect out.
/// Cores with a socket per federate (`zmq`, `tcp`) need ports the broker hands out unchecked.
pub const DEFAULT_CORE: &str = "tcpss";
/// How long a federate tries to join its broker before it gives up with the broker's address.
pub const JOIN_TIMEOUT: Duration = Duration::from_secs(20);
const HELICS_DATA_TYPE_DOUBLE: c_int = 1;
const HELICS_DATA_TYPE_VECTOR: c_int = 4;
const HELICS_FLAG_UNINTERRUPTIBLE: c_int = 1;

impl Helics {
    /// dlopen libhelics at `path` and resolve the functions used here.
    pub fn open(path: &Path) -> Result<Helics, Error> {
        let c_path = CString::new(path.to_string_lossy().as_bytes())
            .map_err(|_| Error::Federation(format!("{}: bad path", path.display())))?;
        // SAFETY: dlopen/dlsym with valid C strings; every symbol is cast to the signature of
        // helics.h (HELICS 3); the library stays loaded for the process.
        unsafe {
            let handle = libc::dlopen(c_path.as_ptr(), libc::RTLD_NOW | libc::RTLD_LOCAL);
            if handle.is_null() {
                let why = CStr::from_ptr(libc::dlerror()).to_string_lossy();
                return err(format!("cannot load libhelics {}: {why}", path.display()));
            }
            let api = match Api::resolve(handle) {
                Ok(api) => api,
                Err(e) => {
                    libc::dlclose(handle);
                    return err(format!("{}: {e}", path.display()));
                }
            };
            Ok(Helics {
                api,
                path: path.to_path_buf(),
            })
        }
    }

    /// Where the library was loaded from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The library's version string.
    pub fn version(&self) -> String {
        // SAFETY: returns a static C string.
        unsafe {
            let v = (self.api.get_version)();
            if v.is_null() {
                return "?".into();
            }
            CStr::from_ptr(v).to_string_lossy().into_owned()
        }
    }

    /// Call `f` with a fresh error object; `Err` naming `what` when it reports an error.
    fn call<T>(&self, what: &str, f: impl FnOnce(E) -> T) -> Result<T, Error> {
        // SAFETY: helicsErrorInitialize returns a plain struct; the message (when set) is a C
        // string owned by the library, copied at once.
        unsafe {
            let mut e = (self.api.error_initialize)();
            let r = f(&mut e);
            if e.error_code != 0 {
                let msg = if e.message.is_null() {
                    String::new()
                } else {
                    CStr::from_ptr(e.message).to_string_lossy().into_owned()
                };
                return err(format!("HELICS: {what}: {msg} (error {})", e.error_code));
            }
            Ok(r)
        }
    }
}

impl Drop for Helics {
    fn drop(&mut self) {
        // SAFETY: every federate of this library was freed (Federate borrows Helics). The
        // library stays mapped: its helper threads may outlive helicsCloseLibrary by a moment.
        unsafe { (self.api.close_library)() };
    }
}

/// libhelics: `explicit` (`--helics-lib`), else `$HELICS_LIB`, else the `helics` wheel in the
/// project's test venv (`target/venv`, made by `cargo xtask test`), else in `$VIRTUAL_ENV`.
pub fn find_library(explicit: Option<&Path>) -> Result<PathBuf, Error> {
    if let Some(p) = explicit {
        return if p.is_file() {
            Ok(p.to_path_buf())
        } else {
            err(format!("--helics-lib {}: no such file", p.display()))
        };
    }
    if let Some(p) = std::env::var_os("HELICS_LIB") {
        let p = PathBuf::from(p);
        return if p.is_file() {
            Ok(p)
        } else {
            err(format!("HELICS_LIB={}: no such file", p.display()))
        };
    }
    let mut venvs = Vec::new();
    if let Some(v) = std::env::var_os("VIRTUAL_ENV") {
        venvs.push(PathBuf::from(v));
    }
    venvs.push(PathBuf::from("target/venv"));
    venvs.push(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .unwrap_or(Path::new("."))
            .join("target/venv"),
    );
    for venv in &venvs {
        let Ok(libs) = std::fs::read_dir(venv.join("lib")) else {
            continue;
        };
        for py in libs.flatten() {
            let install = py.path().join("site-packages/helics/install");
            for lib in ["lib64", "lib"] {
                let p = install.join(lib).join("libhelics.so");
                if p.is_file() {
                    return Ok(p);
                }
            }
        }
    }
    err(format!(
        "libhelics not found: give --helics-lib PATH or HELICS_LIB, or install the `helics` wheel \
         into the test venv (cargo xtask test does; looked in {})",
        venvs
            .iter()
            .map(|v| v.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    ))
}

/// `helics_broker` of the wheel holding `lib` (`install/lib64/libhelics.so` → `install/bin`).
pub fn find_broker(lib: &Path) -> Result<PathBuf, Error> {
    let p = lib
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join("bin").join("helics_broker"));
    match p {
        Some(p) if p.is_file() => Ok(p),
        _ => err(format!(
            "no helics_broker next to {} (expected ../bin/helics_broker)",
            lib.display()
        )),
    }
}

fn cstring(s: &str) -> Result<CString, Error> {
    CString::new(s).map_err(|_| Error::Federation(format!("'{s}': a NUL in a name")))
}

/// A value federate named `name` on a `core` core connecting to `broker`.
fn create_federate(h: &Helics, name: &str, core: &str, broker: &str) -> Result<Handle, Error> {
    // SAFETY: plain constructor.
    let info = unsafe { (h.api.create_federate_info)() };
    if info.is_null() {
        return err("HELICS: cannot create a federate info");
    }
    let result = (|| {
        let core_c = cstring(core)?;
        // SAFETY: a live federate info, C strings alive across the calls.
        h.call("set core type", |e| unsafe {
            (h.api.info_core_type)(info, core_c.as_ptr(), e)
        })?;
        let init = cstring(&format!(
            "--federates=1 --broker={broker} --timeout={}s",
            JOIN_TIMEOUT.as_secs()
        ))?;
        // SAFETY: a live federate info; the string lives across the call.
        h.call("set core init string", |e| unsafe {
            (h.api.info_core_init)(info, init.as_ptr(), e)
        })?;
        // SAFETY: a live federate info.
        h.call("set uninterruptible", |e| unsafe {
            (h.api.info_flag)(info, HELICS_FLAG_UNINTERRUPTIBLE, 1, e)
        })?;
        let n = cstring(name)?;
        let fed = h.call(
            &format!(
                "cannot join the federation at broker {broker} as '{name}' within {} s (no {core} \
                 broker answered there, or it refused the federate: is the address right, is \
                 the broker running, is the name unique?)",
                JOIN_TIMEOUT.as_secs()
            ),
            // SAFETY: a live federate info; the name lives across the call.
            |e| unsafe { (h.api.create_value_federate)(n.as_ptr(), info, e) },
        )?;
        if fed.is_null() {
            return err(format!("HELICS: no federate from broker {broker}"));
        }
        Ok(fed)
    })();
    // SAFETY: freed once; the federate keeps its own copy.
    unsafe { (h.api.info_free)(info) };
    result
}

/// What to run: the system, this federate's components and where its broker is.
#[derive(Debug, Clone, Default)]
pub struct FederateOptions {
    pub system: PathBuf,
    pub components: Vec<String>,
    /// The broker's address, `host` or `host:port`.
    pub broker: String,
    /// HELICS core type (default [`DEFAULT_CORE`]; `zmq`, `tcp`, `zmqss` also work across
    /// machines).
    pub core: Option<String>,
    /// The federate's name (default: the components joined with `+`).
    pub name: Option<String>,
    pub out: Option<PathBuf>,
    pub helics_lib: Option<PathBuf>,
    pub opts: Options,
}

/// How a federate's run went.
#[derive(Debug, Clone)]
pub struct FederateReport {
    pub name: String,
    pub steps: u64,
    /// HELICS time grants of each initialization pass and of each step.
    pub init_rounds: usize,
    pub step_rounds: usize,
    pub init_passes: usize,
    /// Wall time from entering executing mode to the end of the last step.
    pub run_time: Duration,
    pub load_time: Duration,
    pub warnings: Vec<String>,
}

/// A component's outputs that other components read, as one HELICS vector named after the
/// component: one message per component and round, however many values it carries (a message
/// costs tens of µs on its way through the cores and the broker; the values cost nothing).
struct Pack {
    handle: Handle,
    /// Position of each output slot in the vector.
    at: BTreeMap<usize, usize>,
    values: Vec<f64>,
    /// Published this round (a publication) / read this round (an input).
    touched: bool,
}

/// The HELICS side of a running federate.
struct Federate<'a> {
    h: &'a Helics,
    fed: Handle,
    /// The vector of each own component that another federate reads.
    publications: BTreeMap<usize, Pack>,
    /// The vector of each remote component this federate reads.
    inputs: BTreeMap<usize, Pack>,
    /// The change counts of initialization: own components' publications, others' inputs.
    changed_pub: BTreeMap<usize, Handle>,
    changed_in: BTreeMap<usize, Handle>,
    /// The HELICS time granted (one per round), and at the start of the current exchange.
    time: f64,
    base: f64,
    finalized: bool,
    /// This federate's components.
    mine: Vec<bool>,
    /// The source (unit, output slot) and destination unit of each connection.
    ends: Vec<(usize, usize, usize)>,
    /// Values read at their source or taken from HELICS, by connection, to be set at their
    /// destination.
    buf: Vec<f64>,
    /// Per [`Phase`]: the connections whose value arrives at the start of each round, and the
    /// rounds this federate must be granted ([`Schedule`]).
    receive: [Vec<Vec<usize>>; 2],
    granted: [Vec<bool>; 2],
    /// Initialization exchanges so far.
    init_passes: usize,
}

impl Federate<'_> {
    /// The next round: request the next HELICS time and check it is the one granted.
    fn next_round(&mut self) -> Result<(), Error> {
        self.round(self.time + 1.0)
    }

    /// Round `want`: request that HELICS time and check it is the one granted.
    fn round(&mut self, want: f64) -> Result<(), Error> {
        let (h, fed) = (self.h, self.fed);
        // SAFETY: a live federate handle; the error object is ours.
        let got = h.call("helicsFederateRequestTime", |e| unsafe {
            (h.api.request_time)(fed, want, e)
        })?;
        if got != want {
            return err(format!(
                "HELICS granted time {got} instead of {want} (another federate left or the federation is not of this system)"
            ));
        }
        self.time = want;
        Ok(())
    }

    /// Publish the vectors of the components that produced values this round.
    fn publish_packs(&mut self) -> Result<(), Error> {
        let h = self.h;
        for p in self.publications.values_mut().filter(|p| p.touched) {
            p.touched = false;
            // SAFETY: a live publication; `values` holds `len` doubles.
            h.call("helicsPublicationPublishVector", |e| unsafe {
                (h.api.publish_vector)(p.handle, p.values.as_ptr(), p.values.len() as c_int, e)
            })?;
        }
        Ok(())
    }

    /// Output `slot` of remote component `src` as granted this round (its vector read once).
    fn take(&mut self, src: usize, slot: usize) -> Result<f64, Error> {
        let h = self.h;
        let p = self
            .inputs
            .get_mut(&src)
            .ok_or_else(|| Error::Federation(format!("no input of component #{src}")))?;
        if !p.touched {
            let mut got: c_int = 0;
            let want = p.values.len();
            // SAFETY: a live input; `values` has room for `want` doubles.
            h.call("helicsInputGetVector", |e| unsafe {
                (h.api.input_get_vector)(
                    p.handle,
                    p.values.as_mut_ptr(),
                    want as c_int,
                    &mut got,
                    e,
                )
            })?;
            if got as usize != want {
                return err(format!(
                    "a vector of {got} values from component #{src}, {want} expected (is every federate of this system and version?)"
                ));
            }
            p.touched = true;
        }
        Ok(p.values[p.at[&slot]])
    }

    /// A new round: every remote vector is read afresh.
    fn untouch_inputs(&mut self) {
        for p in self.inputs.values_mut() {
            p.touched = false;
        }
    }

    fn publish(&self, p: Handle, v: f64) -> Result<(), Error> {
        let h = self.h;
        // SAFETY: a live publication handle.
        h.call("helicsPublicationPublishDouble", |e| unsafe {
            (h.api.publish_double)(p, v, e)
        })
    }

    fn get(&self, i: Handle) -> Result<f64, Error> {
        let h = self.h;
        // SAFETY: a live input handle.
        h.call("helicsInputGetDouble", |e| unsafe {
            (h.api.input_get_double)(i, e)
        })
    }

    fn finalize(&mut self) -> Result<(), Error> {
        if self.finalized {
            return Ok(());
        }
        self.finalized = true;
        let (h, fed) = (self.h, self.fed);
        // SAFETY: a live federate handle.
        h.call("helicsFederateFinalize", |e| unsafe {
            (h.api.finalize)(fed, e)
        })
    }
}

impl Drop for Federate<'_> {
    fn drop(&mut self) {
        let _ = self.finalize();
        // SAFETY: finalized; freed once.
        unsafe { (self.h.api.federate_free)(self.fed) };
    }
}

/// The federate as the coupling core's transport: a value between two of its own components
/// is copied, one to or from another federate travels in that component's vector.
impl Transport for Federate<'_> {
    fn begin_round(&mut self, phase: Phase, round: usize) -> Result<(), Error> {
        if round == 0 {
            self.base = self.time;
            return Ok(());
        }
        // Initialization passes end on a count every federate publishes: all take part.
        let p = phase as usize;
        if phase != Phase::Init && !self.granted[p][round] {
            return Ok(());
        }
        self.round(self.base + round as f64)?;
        self.untouch_inputs();
        for k in 0..self.receive[p][round].len() {
            let i = self.receive[p][round][k];
            let (src, slot, dst) = self.ends[i];
            if self.mine[dst] && !self.mine[src] {
                self.buf[i] = self.take(src, slot)?;
            }
        }
        Ok(())
    }

    fn carry(&mut self, i: usize, link: &Link, raw: f64) {
        if self.mine[link.dst()] {
            self.buf[i] = raw;
        } else if let Some(p) = self.publications.get_mut(&link.src()) {
            p.values[p.at[&link.slot()]] = raw;
            p.touched = true;
        }
    }

    fn deliver(&mut self, i: usize, _: &Link) -> Result<f64, Error> {
        Ok(self.buf[i])
    }

    fn end_round(&mut self) -> Result<(), Error> {
        self.publish_packs()
    }

    /// Every federate's count: own components' published (the count on the first), the
    /// others' read one round later.
    fn settled(&mut self, changed: usize) -> Result<bool, Error> {
        let mut first = true;
        for p in self.changed_pub.values() {
            self.publish(*p, if first { changed as f64 } else { 0.0 })?;
            first = false;
        }
        self.next_round()?;
        let mut total = changed as f64;
        for i in self.changed_in.values() {
            total += self.get(*i)?;
        }
        self.init_passes += 1;
        Ok(total == 0.0)
    }
}

/// Run `o.components` of the system as one HELICS federate to the stop time; the federate's
/// outputs go to `o.out` (CSV, as `cosim --out` writes them) when given.
pub fn run_federate(o: &FederateOptions) -> Result<FederateReport, Error> {
    let lib_path = find_library(o.helics_lib.as_deref())?;
    let helics = Helics::open(&lib_path)?;
    let started = Instant::now();
    let package = ssp::read(&o.system)?;
    let mut system = System::builder(&package).load()?;
    let names = component_names(&package);
    let mut mine = vec![false; names.len()];
    for c in &o.components {
        match names.iter().position(|n| n == c) {
            Some(k) => mine[k] = true,
            None => {
                return err(format!(
                    "--component {c}: no such component in {} ({})",
                    o.system.display(),
                    names.join(", ")
                ))
            }
        }
    }
    if !mine.iter().any(|&m| m) {
        return err("--component: no component given");
    }
    system.core_mut().set_local(&mine);
    let name = o.name.clone().unwrap_or_else(|| o.components.join("+"));
    let mut init = schedule(&system, system.order(Phase::Init), Phase::Init);
    let mut step = schedule(&system, system.order(Phase::Step), Phase::Step);
    init.grant_for(&system, &mine);
    step.grant_for(&system, &mine);
    let links = system.core().links();
    if std::env::var_os("COSIM_SCHEDULE").is_some() {
        for (j, r) in step.rounds().iter().enumerate() {
            for e in r {
                let (Event::Local(i) | Event::Produce(i) | Event::Consume(i)) = *e;
                eprintln!("round {j}: {e:?} {}", links[i].label());
            }
        }
    }
    let ends = links.iter().map(|l| (l.src(), l.slot(), l.dst())).collect();
    let (start, stop, h) = system.experiment(&o.opts)?;
    let load_time = started.elapsed();
    let init_rounds = init.rounds().len();
    let step_rounds = step.grants();
    let (init_plan, init_receive, init_granted) = init.into_parts();
    let (step_plan, step_receive, step_granted) = step.into_parts();

    // The federate and its interfaces.
    let core = o.core.as_deref().unwrap_or(DEFAULT_CORE);
    let fed = create_federate(&helics, &name, core, &o.broker)?;
    let mut fed = Federate {
        h: &helics,
        fed,
        publications: BTreeMap::new(),
        inputs: BTreeMap::new(),
        changed_pub: BTreeMap::new(),
        changed_in: BTreeMap::new(),
        time: 0.0,
        base: 0.0,
        finalized: false,
        buf: vec![0.0; system.core().links().len()],
        mine,
        ends,
        receive: [init_receive, step_receive],
        granted: [init_granted, step_granted],
        init_passes: 0,
    };
    let plans: Plans = [init_plan, step_plan];
    // One vector per component that another component reads (see [`Pack`]).
    for (u, at) in packed_slots(&system) {
        let name = cstring(system.core().units()[u].name())?;
        let links = system.core().links();
        let mine = fed.mine[u];
        let wanted = if mine {
            links.iter().any(|l| l.src() == u && !fed.mine[l.dst()])
        } else {
            links.iter().any(|l| l.src() == u && fed.mine[l.dst()])
        };
        if !wanted {
            continue;
        }
        let handle = if mine {
            // SAFETY: a live federate; the name is a C string alive across the call.
            helics.call("register publication", |e| unsafe {
                (helics.api.register_global_publication)(
                    fed.fed,
                    name.as_ptr(),
                    HELICS_DATA_TYPE_VECTOR,
                    c"".as_ptr(),
                    e,
                )
            })?
        } else {
            // SAFETY: as above.
            helics.call("register subscription", |e| unsafe {
                (helics.api.register_subscription)(fed.fed, name.as_ptr(), c"".as_ptr(), e)
            })?
        };
        let pack = Pack {
            handle,
            values: vec![0.0; at.len()],
            at,
            touched: false,
        };
        if mine {
            fed.publications.insert(u, pack);
        } else {
            fed.inputs.insert(u, pack);
        }
    }
    for (k, n) in names.iter().enumerate() {
        let k_name = cstring(&format!("_cosim.changed.{n}"))?;
        if fed.mine[k] {
            // SAFETY: as above.
            let p = helics.call("register publication", |e| unsafe {
                (helics.api.register_global_publication)(
                    fed.fed,
                    k_name.as_ptr(),
                    HELICS_DATA_TYPE_DOUBLE,
                    c"".as_ptr(),
                    e,
                )
            })?;
            fed.changed_pub.insert(k, p);
        } else {
            // SAFETY: as above.
            let i = helics.call("register subscription", |e| unsafe {
                (helics.api.register_subscription)(fed.fed, k_name.as_ptr(), c"".as_ptr(), e)
            })?;
            fed.changed_in.insert(k, i);
        }
    }
    let fed_ptr = fed.fed;
    helics.call(
        "helicsFederateEnterExecutingMode (is every federate of the system running?)",
        // SAFETY: a live federate.
        |e| unsafe { (helics.api.enter_executing_mode)(fed_ptr, e) },
    )?;
    let run_started = Instant::now();

    let mut csv = o.out.as_deref().map(CsvWriter::new);
    let mut report = FederateReport {
        name: name.clone(),
        steps: 0,
        init_rounds,
        step_rounds,
        init_passes: 0,
        run_time: Duration::ZERO,
        load_time,
        warnings: Vec::new(),
    };
    let result = drive(
        &mut system,
        &plans,
        &mut fed,
        &mut csv,
        (start, stop, h),
        &mut report,
    );
    report.init_passes = fed.init_passes;
    let end = match &result {
        Ok(()) => End::Completed,
        Err(e) => End::Failed {
            at: seconds(start),
            error: e.to_string(),
        },
    };
    if let Some(c) = csv.as_mut() {
        c.finish(&end)?;
    }
    report.run_time = run_started.elapsed();
    result?;
    fed.finalize()?;
    report.warnings = system.core_mut().take_warnings();
    Ok(report)
}

/// Initialize, exchange and step as the Jacobi master does, over this federate's units: the
/// coupling core's calls, with the federate as its transport and its rounds as the plans.
fn drive(
    system: &mut System,
    plans: &Plans,
    fed: &mut Federate,
    csv: &mut Option<CsvWriter>,
    (start, stop, step): (i64, i64, i64),
    report: &mut FederateReport,
) -> Result<(), Error> {
    let core = system.core_mut();
    core.initialize(start, stop, plans, fed)
        .map_err(|e| Error::Initialization(Box::new(e)))?;
    let columns = core.columns();
    if let Some(c) = csv.as_mut() {
        c.start(&RunInfo {
            system: &report.name,
            columns: &columns,
            start: seconds(start),
            stop: seconds(stop),
            step: seconds(step),
            record: &[],
        })?;
    }
    let step_plan = &plans[Phase::Step as usize];
    let mut t = start;
    loop {
        core.sample(t)?;
        if let Some(c) = csv.as_mut() {
            c.sample(core.row())?;
        }
        if t >= stop {
            break;
        }
        let h = step.min(stop - t);
        let step_error = |e: Error| Error::Step {
            from: seconds(t),
            to: seconds(t + h),
            algorithm: None,
            cause: Box::new(e),
        };
        core.step_all(t, h).map_err(step_error)?;
        // No new round to start the exchange (the last round of an exchange publishes
        // nothing); one at least per step, so that the federates go in step.
        if step_plan.len() == 1 {
            fed.next_round().map_err(step_error)?;
        }
        core.exchange(Phase::Step, step_plan, fed)
            .map_err(step_error)?;
        report.steps += 1;
        t += h;
    }
    core.terminate()
}

/// The system's component names, in SSD order.
fn component_names(package: &ssp::Package) -> Vec<String> {
    package
        .system
        .components
        .iter()
        .map(|c| c.name.clone())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_library_is_named() {
        let e = find_library(Some(Path::new("/nonexistent/libhelics.so"))).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/libhelics.so"), "{e}");
    }
}
