//! What the allocation tests share: an allocator that counts, and an in-process host of a DLL's functions (its structs and arrays laid out from the DLL's `Layout`).

use dvpp_realcode::ffi::{self, Instance};
use dvpp_realcode::info::{Field, Kind, Layout};
use std::alloc::{GlobalAlloc, Layout as MemLayout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts allocations (and reallocations) of this test binary: the DLL's code runs in it.
pub struct Counting;

pub static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: MemLayout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: the caller's layout, forwarded.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: MemLayout) {
        // SAFETY: a block this allocator (the system's) gave.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: MemLayout, n: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: as above.
        unsafe { System.realloc(p, l, n) }
    }
}

pub fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// One instance's structs and arrays, 8-byte aligned.
pub struct Host {
    pub inst: Box<Instance>,
    inputs: Vec<u64>,
    _outputs: Vec<u64>,
    parameters: Vec<u64>,
    _ints: Vec<i32>,
}

fn put(buf: &mut [u64], f: &Field, x: f64) {
    let base = buf.as_mut_ptr().cast::<u8>();
    // SAFETY: the field lies within the buffer laid out for its group.
    unsafe {
        match f.kind {
            Kind::Real => base.add(f.offset).cast::<f64>().write_unaligned(x),
            _ => base.add(f.offset).cast::<i32>().write_unaligned(x as i32),
        }
    }
}

impl Host {
    pub fn new(l: &Layout) -> Host {
        let words = |b: usize| vec![0u64; b.div_ceil(8).max(1)];
        let mut h = Host {
            inst: Box::new(Instance::unattached()),
            inputs: words(l.inputs.size),
            _outputs: words(l.outputs.size),
            parameters: words(l.parameters.size),
            _ints: vec![0; l.spec.state_words],
        };
        h.inst.external_inputs = h.inputs.as_mut_ptr().cast();
        h.inst.external_outputs = h._outputs.as_mut_ptr().cast();
        h.inst.parameters = h.parameters.as_mut_ptr().cast();
        h.inst.int_states = h._ints.as_mut_ptr();
        for f in &l.parameters.fields {
            put(&mut h.parameters, f, f.start);
        }
        h
    }

    pub fn parameter(&mut self, l: &Layout, name: &str, x: f64) {
        let f = l
            .parameters
            .find(name)
            .unwrap_or_else(|| panic!("no parameter {name}"));
        put(&mut self.parameters, f, x);
    }

    pub fn input(&mut self, l: &Layout, name: &str, x: f64) {
        let f = l
            .inputs
            .find(name)
            .unwrap_or_else(|| panic!("no input {name}"));
        put(&mut self.inputs, f, x);
    }

    pub fn error(&self) -> String {
        if self.inst.last_error_message.is_null() {
            return String::new();
        }
        // SAFETY: the DLL's NUL-terminated message.
        unsafe { std::ffi::CStr::from_ptr(self.inst.last_error_message) }
            .to_string_lossy()
            .into_owned()
    }
}

/// The return value `r` of `what` is not an error.
pub fn ok(r: i32, what: &str, h: &Host) {
    assert!(r != ffi::RETURN_ERROR, "{what}: {}", h.error());
}
