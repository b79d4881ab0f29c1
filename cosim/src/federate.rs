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
//! the federate and its interfaces, the rounds and their grants, and the launcher.

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
/// How long the launcher waits for its broker to listen.
const BROKER_TIMEOUT: Duration = Duration::from_secs(20);
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

/// An exchange split into rounds: the events of each round in the master's order, and the
/// connections whose value arrives (is taken from HELICS) at the start of each round.
#[derive(Debug, Default)]
struct Schedule {
    rounds: Vec<Vec<Event>>,
    receive: Vec<Vec<usize>>,
    /// The rounds this federate must be granted: those in which it takes a value from or
    /// publishes one to another federate, and the last (so that no publication of the next
    /// exchange overtakes a read of this one). It skips the others: a round costs a message
    /// only from the federates that take part in it.
    granted: Vec<bool>,
}

impl Schedule {
    /// Mark the rounds a federate of the units `mine` must be granted ([`Schedule::granted`]).
    fn grant_for(&mut self, sys: &System, mine: &[bool]) {
        let links = sys.core().links();
        let remote = |i: usize| mine[links[i].src()] != mine[links[i].dst()];
        let last = self.rounds.len() - 1;
        self.granted = (0..self.rounds.len())
            .map(|j| {
                j == last
                    || self.receive[j]
                        .iter()
                        .any(|&i| remote(i) && mine[links[i].dst()])
                    || self.rounds[j].iter().any(|e| match *e {
                        Event::Produce(i) => remote(i) && mine[links[i].src()],
                        Event::Local(_) | Event::Consume(_) => false,
                    })
            })
            .collect();
    }
}

/// The rounds of one exchange walking `order`: a connection between two components is read at
/// its source in the source's current round and set at its destination one round later at the
/// earliest; a source publishes an output once per round (a second read of it after an input
/// that feeds through was set waits for the next round).
fn schedule(sys: &System, order: &[usize], phase: Phase) -> Schedule {
    let n = sys.units();
    let mut round = vec![0usize; n];
    let mut published: Vec<Option<usize>> = vec![None; n];
    let mut dirty = vec![false; n];
    let mut s = Schedule::default();
    let put = |s: &mut Schedule, r: usize, e: Event| {
        while s.rounds.len() <= r {
            s.rounds.push(Vec::new());
            s.receive.push(Vec::new());
        }
        s.rounds[r].push(e);
    };
    for &i in order {
        let l = &sys.core().links()[i];
        let (src, dst) = (l.src(), l.dst());
        if src == dst {
            put(&mut s, round[src], Event::Local(i));
        } else {
            if published[src] == Some(round[src]) && dirty[src] {
                round[src] += 1;
            }
            let p = round[src];
            published[src] = Some(p);
            dirty[src] = false;
            put(&mut s, p, Event::Produce(i));
            round[dst] = round[dst].max(p + 1);
            put(&mut s, round[dst], Event::Consume(i));
            s.receive[p + 1].push(i);
        }
        if l.feeds(phase) {
            dirty[dst] = true;
        }
    }
    if s.rounds.is_empty() {
        s.rounds.push(Vec::new());
        s.receive.push(Vec::new());
    }
    s
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

/// The outputs of each component that a component other than itself reads, in slot order:
/// the same for every federate, whatever the grouping.
fn packed_slots(sys: &System) -> BTreeMap<usize, BTreeMap<usize, usize>> {
    let mut slots: BTreeMap<usize, std::collections::BTreeSet<usize>> = BTreeMap::new();
    for l in sys.core().links().iter().filter(|l| l.src() != l.dst()) {
        slots.entry(l.src()).or_default().insert(l.slot());
    }
    slots
        .into_iter()
        .map(|(u, s)| (u, s.into_iter().enumerate().map(|(k, s)| (s, k)).collect()))
        .collect()
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
        for (j, r) in step.rounds.iter().enumerate() {
            for e in r {
                let (Event::Local(i) | Event::Produce(i) | Event::Consume(i)) = *e;
                eprintln!("round {j}: {e:?} {}", links[i].label());
            }
        }
    }
    let ends = links.iter().map(|l| (l.src(), l.slot(), l.dst())).collect();
    let (start, stop, h) = system.experiment(&o.opts)?;
    let load_time = started.elapsed();
    let init_rounds = init.rounds.len();
    let step_rounds = step.granted[1..].iter().filter(|&&g| g).count().max(1);

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
        receive: [init.receive, step.receive],
        granted: [init.granted, step.granted],
        init_passes: 0,
    };
    let plans: Plans = [init.rounds, step.rounds];
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

/// A federation on one machine: the system, its federates' components, where the results go.
#[derive(Debug, Clone, Default)]
pub struct FederationOptions {
    pub system: PathBuf,
    /// `a,b;c;d`: the components of each federate; components left out run one per federate.
    pub groups: Option<String>,
    pub out: Option<PathBuf>,
    pub helics_lib: Option<PathBuf>,
    pub opts: Options,
    /// HELICS core type (default [`DEFAULT_CORE`]).
    pub core: Option<String>,
    /// The broker's time coordination (default: [`Timing::for_federates`]).
    pub timing: Option<Timing>,
    /// Where the federates write their CSVs (default: next to `out`).
    pub work_dir: Option<PathBuf>,
}

/// How a federation went.
#[derive(Debug, Clone)]
pub struct FederationReport {
    pub federates: Vec<Vec<String>>,
    pub rows: usize,
    /// Wall time from starting the broker to the last federate's exit.
    pub wall: Duration,
    /// Each federate's printed summary (its last stdout line).
    pub summaries: Vec<String>,
    /// The commands to run the same federation on several machines.
    pub commands: Vec<String>,
}

/// The federates of `groups` over `components` (in SSD order; unlisted ones alone).
pub fn groups(components: &[String], spec: Option<&str>) -> Result<Vec<Vec<String>>, Error> {
    let mut out: Vec<Vec<String>> = Vec::new();
    let mut seen = Vec::new();
    for g in spec
        .unwrap_or("")
        .split(';')
        .filter(|g| !g.trim().is_empty())
    {
        let mut group = Vec::new();
        for c in g.split(',').map(str::trim).filter(|c| !c.is_empty()) {
            if !components.iter().any(|n| n == c) {
                return err(format!(
                    "--groups: no component '{c}' ({})",
                    components.join(", ")
                ));
            }
            if seen.iter().any(|s| s == c) {
                return err(format!("--groups: '{c}' is in two groups"));
            }
            seen.push(c.to_owned());
            group.push(c.to_owned());
        }
        out.push(group);
    }
    for c in components {
        if !seen.contains(c) {
            out.push(vec![c.clone()]);
        }
    }
    Ok(out)
}

/// Split one CSV line into its fields (as written: quoted fields may hold commas).
fn fields(line: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let (mut start, mut quoted) = (0, false);
    for (i, ch) in line.char_indices() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => {
                out.push(&line[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&line[start..]);
    out
}

/// A CSV header field's name (unquoted).
fn unquote(f: &str) -> String {
    f.strip_prefix('"')
        .and_then(|f| f.strip_suffix('"'))
        .map_or_else(|| f.to_owned(), |f| f.replace("\"\"", "\""))
}

/// Merge the federates' CSVs (same times) into `out`, columns in `order` (the master's).
fn merge(parts: &[PathBuf], order: &[String], out: &Path) -> Result<usize, Error> {
    use std::io::{BufRead, BufReader, BufWriter, Write};
    let io = |p: &Path, e: std::io::Error| Error::Federation(format!("{}: {e}", p.display()));
    let mut readers = Vec::new();
    // (part, field) of each output column.
    let mut at: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let mut header_text: BTreeMap<String, String> = BTreeMap::new();
    for (k, p) in parts.iter().enumerate() {
        let f = std::fs::File::open(p).map_err(|e| io(p, e))?;
        let mut lines = BufReader::new(f).lines();
        let header = lines
            .next()
            .ok_or_else(|| Error::Federation(format!("{}: empty", p.display())))?
            .map_err(|e| io(p, e))?;
        for (j, f) in fields(&header).into_iter().enumerate() {
            let name = unquote(f);
            if j > 0 || k == 0 {
                header_text.insert(name.clone(), f.to_owned());
                at.insert(name, (k, j));
            }
        }
        readers.push(lines);
    }
    let picks: Vec<(usize, usize)> = order
        .iter()
        .map(|c| {
            at.get(c)
                .copied()
                .ok_or_else(|| Error::Federation(format!("no federate wrote column '{c}'")))
        })
        .collect::<Result<_, _>>()?;
    let file = std::fs::File::create(out).map_err(|e| io(out, e))?;
    let mut w = BufWriter::new(file);
    let head: Vec<&str> = order.iter().map(|c| header_text[c].as_str()).collect();
    writeln!(w, "{}", head.join(",")).map_err(|e| io(out, e))?;
    let mut rows = 0;
    loop {
        let mut lines = Vec::with_capacity(readers.len());
        for (k, r) in readers.iter_mut().enumerate() {
            match r.next() {
                Some(l) => lines.push(l.map_err(|e| io(&parts[k], e))?),
                None => break,
            }
        }
        if lines.len() < readers.len() {
            if !lines.is_empty() {
                return err("the federates' CSVs have different numbers of rows");
            }
            break;
        }
        let split: Vec<Vec<&str>> = lines.iter().map(|l| fields(l)).collect();
        if split.iter().any(|f| f[0] != split[0][0]) {
            return err(format!(
                "the federates' CSVs disagree on the time at row {rows}"
            ));
        }
        let row: Vec<&str> = picks.iter().map(|&(k, j)| split[k][j]).collect();
        writeln!(w, "{}", row.join(",")).map_err(|e| io(out, e))?;
        rows += 1;
    }
    w.flush().map_err(|e| io(out, e))?;
    Ok(rows)
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

/// How the broker coordinates time ([`FederationOptions::timing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Timing {
    /// HELICS's default: the federates' cores negotiate each grant among themselves.
    Distributed,
    /// One coordinator at the broker: every round is a barrier, a grant one request to the
    /// broker and one answer, whatever the number of federates.
    Global,
}

/// From this many federates on, [`Timing::Global`] by default. Measured on case study I (1 s at
/// 1 ms, this project's 2-core machine, idle): distributed 1.27, 1.96-2.28, 5.5 and 11.6 ms per
/// step for 2, 3, 4 and 5 federates, global 2.3-2.5, 2.7, 2.7 and 2.9 ms (docs/scaling.md).
pub const GLOBAL_FROM: usize = 4;

impl Timing {
    /// The default for `federates` federates.
    pub fn for_federates(federates: usize) -> Timing {
        if federates >= GLOBAL_FROM {
            Timing::Global
        } else {
            Timing::Distributed
        }
    }

    /// The broker's options for it.
    fn flags(self) -> &'static [&'static str] {
        match self {
            Timing::Distributed => &["--loglevel=error"],
            Timing::Global => &["--globaltime", "--loglevel=error"],
        }
    }
}

/// A child process of the launcher, which ends with it (SIGTERM when the launcher dies, also by
/// SIGKILL, so that no broker or federate outlives its federation).
fn child(program: &Path) -> std::process::Command {
    use std::os::unix::process::CommandExt;
    let mut c = std::process::Command::new(program);
    // SAFETY: prctl is async-signal-safe; it only sets this child's parent-death signal.
    unsafe {
        c.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    c
}

/// End a child and reap it.
fn stop(c: &mut std::process::Child) {
    let _ = c.kill();
    let _ = c.wait();
}

/// `helics_broker` for `federates` federates on loopback, on a port the kernel chooses and holds
/// for it (port 0): no other process can take it between choosing and listening.
fn start_broker(
    exe: &Path,
    core: &str,
    federates: usize,
    timing: Timing,
) -> Result<std::process::Child, Error> {
    child(exe)
        .args(["-f", &federates.to_string()])
        .arg(format!("--coretype={core}"))
        .args(timing.flags())
        .arg("--local_interface=tcp://127.0.0.1")
        .arg("--port=0")
        .stdout(std::process::Stdio::null())
        .spawn()
        .map_err(|e| Error::Federation(format!("cannot start {}: {e}", exe.display())))
}

/// The port the broker listens on, once it does (within [`BROKER_TIMEOUT`]).
fn wait_listening(broker: &mut std::process::Child, exe: &Path) -> Result<u16, Error> {
    let since = Instant::now();
    loop {
        if let Some(port) = crate::listen::port_of(broker.id()) {
            return Ok(port);
        }
        if let Ok(Some(status)) = broker.try_wait() {
            return err(format!("{} ended at once ({status})", exe.display()));
        }
        if let Some(signal) = crate::interrupt::requested() {
            return err(format!(
                "stopped by signal {signal} while the broker started"
            ));
        }
        if since.elapsed() > BROKER_TIMEOUT {
            return err(format!(
                "{} does not listen on 127.0.0.1 after {} s",
                exe.display(),
                BROKER_TIMEOUT.as_secs()
            ));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Run the system as a federation on this machine: `helics_broker` on loopback, one
/// `exe federate` process per group, their CSVs merged into `o.out` in the master's column order.
pub fn run_federation(o: &FederationOptions, exe: &Path) -> Result<FederationReport, Error> {
    use std::process::Stdio;
    let lib = find_library(o.helics_lib.as_deref())?;
    let broker_exe = find_broker(&lib)?;
    let package = ssp::read(&o.system)?;
    let names = component_names(&package);
    let feds = groups(&names, o.groups.as_deref())?;
    let order = System::builder(&package).load()?.columns();
    let out = o.out.clone().unwrap_or_else(|| {
        PathBuf::from(format!(
            "{}.csv",
            o.system
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("system")
        ))
    });
    let dir = o.work_dir.clone().unwrap_or_else(|| {
        let mut d = out.as_os_str().to_owned();
        d.push(".federates");
        PathBuf::from(d)
    });
    std::fs::create_dir_all(&dir)
        .map_err(|e| Error::Federation(format!("{}: {e}", dir.display())))?;
    let core = o.core.as_deref().unwrap_or(DEFAULT_CORE);
    let started = Instant::now();
    let coordination = o.timing.unwrap_or(Timing::for_federates(feds.len()));
    let mut broker = start_broker(&broker_exe, core, feds.len(), coordination)?;
    let port = match wait_listening(&mut broker, &broker_exe) {
        Ok(p) => p,
        Err(e) => {
            stop(&mut broker);
            return Err(e);
        }
    };
    let address = format!("127.0.0.1:{port}");
    let mut timing = vec!["--core".to_owned(), core.to_owned()];
    if let Some(s) = o.opts.stop {
        timing.extend(["--stop".to_owned(), s.to_string()]);
    }
    if let Some(s) = o.opts.step {
        timing.extend(["--step".to_owned(), s.to_string()]);
    }
    let mut children = Vec::new();
    let mut parts = Vec::new();
    let mut commands = vec![format!(
        "{} -f {} --coretype={core} {} --local_interface=tcp://BROKER_HOST --port={port}",
        broker_exe.display(),
        feds.len(),
        coordination.flags().join(" ")
    )];
    let mut failure = None;
    for (k, g) in feds.iter().enumerate() {
        let name = format!("fed{k}");
        let csv = dir.join(format!("{name}.csv"));
        let args = |broker: &str, csv: &Path| -> Vec<String> {
            let mut a = vec![
                "federate".to_owned(),
                o.system.display().to_string(),
                "--component".to_owned(),
                g.join(","),
                "--broker".to_owned(),
                broker.to_owned(),
                "--name".to_owned(),
                name.clone(),
                "--out".to_owned(),
                csv.display().to_string(),
                "--helics-lib".to_owned(),
                lib.display().to_string(),
            ];
            a.extend(timing.iter().cloned());
            a
        };
        commands.push(format!(
            "{} {}",
            exe.display(),
            args(
                &format!("BROKER_HOST:{port}"),
                Path::new(&format!("{name}.csv"))
            )
            .join(" ")
        ));
        match child(exe)
            .args(args(&address, &csv))
            .stdout(Stdio::piped())
            .spawn()
        {
            Ok(c) => children.push(c),
            Err(e) => {
                failure = Some(Error::Federation(format!(
                    "cannot start {}: {e}",
                    exe.display()
                )));
                break;
            }
        }
        parts.push(csv);
    }
    // Wait for every federate; when one fails, the others would wait for it: stop them.
    let mut summaries = vec![String::new(); children.len()];
    let mut running: Vec<Option<std::process::Child>> = children.into_iter().map(Some).collect();
    while failure.is_none() && running.iter().any(Option::is_some) {
        if let Some(signal) = crate::interrupt::requested() {
            failure = Some(Error::Federation(format!(
                "stopped by signal {signal}: the broker and the federates were stopped"
            )));
            break;
        }
        for k in 0..running.len() {
            let Some(c) = running[k].as_mut() else {
                continue;
            };
            match c.try_wait() {
                Ok(None) => continue,
                Ok(Some(status)) if status.success() => {
                    let c = running[k].take().expect("running");
                    if let Ok(out) = c.wait_with_output() {
                        summaries[k] = String::from_utf8_lossy(&out.stdout)
                            .lines()
                            .last()
                            .unwrap_or("")
                            .to_owned();
                    }
                }
                Ok(Some(status)) => {
                    running[k] = None;
                    failure = Some(Error::Federation(format!(
                        "federate fed{k} ({}) failed ({status}); the others were stopped",
                        feds[k].join(",")
                    )));
                }
                Err(e) => failure = Some(Error::Federation(format!("federate fed{k}: {e}"))),
            }
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    for c in running.iter_mut().flatten() {
        stop(c);
    }
    if failure.is_some() {
        // The broker waits for federates that never came: stop it (it is our child).
        stop(&mut broker);
    }
    let _ = broker.wait();
    let wall = started.elapsed();
    if let Some(e) = failure {
        return Err(e);
    }
    let rows = merge(&parts, &order, &out)?;
    Ok(FederationReport {
        federates: feds,
        rows,
        wall,
        summaries,
        commands,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn groups_cover_every_component_once() {
        let all = names(&["grid", "operator", "wind", "pv", "bess"]);
        let g = groups(&all, Some("grid,operator; wind ,pv")).unwrap();
        assert_eq!(
            g,
            vec![
                names(&["grid", "operator"]),
                names(&["wind", "pv"]),
                names(&["bess"])
            ]
        );
        assert_eq!(groups(&all, None).unwrap().len(), 5);
        assert!(groups(&all, Some("grid;grid"))
            .unwrap_err()
            .to_string()
            .contains("two groups"));
        assert!(groups(&all, Some("nosuch"))
            .unwrap_err()
            .to_string()
            .contains("'nosuch'"));
    }

    #[test]
    fn csv_fields_keep_quoted_commas() {
        assert_eq!(fields("time,\"a,b\",c"), vec!["time", "\"a,b\"", "c"]);
        assert_eq!(unquote("\"a,\"\"b\"\"\""), "a,\"b\"");
        assert_eq!(unquote("grid.pcc.f"), "grid.pcc.f");
    }

    #[test]
    fn a_missing_library_is_named() {
        let e = find_library(Some(Path::new("/nonexistent/libhelics.so"))).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/libhelics.so"), "{e}");
    }
}
