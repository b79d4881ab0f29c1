//! A small pool of worker threads (std only) for stepping units in parallel: the calling thread
//! works too; each thread works through its own contiguous block of the items, the same block
//! every round (its units' state stays in its core's cache), claiming chunks from the block's
//! cursor, and then takes chunks from the other blocks (a slow unit or a late thread does not
//! hold up the others); idle workers spin for a short while, then park.
//!
//! Why not rayon: `ThreadPool::install` from the master's thread parks that thread on a latch
//! while the pool works (one core idle, a wake-up per step in both directions), and a step of
//! a small system lasts a few µs; here the master's thread takes part and a round costs one
//! atomic increment per chunk plus an unpark. About 150 lines, no dependency.

use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// How long an idle worker spins before it parks: the master's work between two parallel
/// steps (exchange, sampling, observers) usually takes less, so workers are ready at once.
const SPIN: Duration = Duration::from_micros(100);

/// One round's work, on the stack of the thread that called [`Pool::for_each`]; called with
/// the thread's number (the caller 0, workers 1, 2, ...).
struct Task<'a> {
    run: &'a (dyn Fn(usize) + Sync),
}

/// A cursor on a cache line of its own.
#[repr(align(64))]
struct Cursor(AtomicUsize);

struct Shared {
    /// Bumped once per round, after `task` was set for it.
    generation: AtomicU64,
    /// The current round's task: valid while its round is not retired or a worker is in it.
    task: AtomicPtr<Task<'static>>,
    /// The last round that accepts no more workers.
    retired: AtomicU64,
    /// Workers inside a round (entered before it was retired).
    active: AtomicUsize,
    panicked: AtomicBool,
    stop: AtomicBool,
}

/// Worker threads that run rounds of work with the caller.
pub(crate) struct Pool {
    shared: Arc<Shared>,
    workers: Vec<JoinHandle<()>>,
    /// The next unclaimed item of each thread's block (set by the caller before each round).
    cursors: Vec<Cursor>,
}

/// A pointer to the items of a round; each index is claimed by exactly one thread.
struct Items<T>(*mut T);

// SAFETY: the pointer is only dereferenced at indices claimed once through the round's cursors,
// so each `&mut T` exists on one thread at a time; `T: Send` lets that thread use it.
unsafe impl<T: Send> Sync for Items<T> {}

impl<T> Items<T> {
    /// The address of item `k` (a method, so that closures capture the whole `Items`).
    fn at(&self, k: usize) -> *mut T {
        self.0.wrapping_add(k)
    }
}

impl Pool {
    /// A pool for rounds on `threads` threads: the caller and `threads - 1` workers.
    pub(crate) fn new(threads: usize) -> std::io::Result<Pool> {
        let shared = Arc::new(Shared {
            generation: AtomicU64::new(0),
            task: AtomicPtr::new(std::ptr::null_mut()),
            retired: AtomicU64::new(0),
            active: AtomicUsize::new(0),
            panicked: AtomicBool::new(false),
            stop: AtomicBool::new(false),
        });
        let threads = threads.max(1);
        let mut pool = Pool {
            shared,
            workers: Vec::new(),
            cursors: (0..threads).map(|_| Cursor(AtomicUsize::new(0))).collect(),
        };
        for k in 1..threads {
            let shared = Arc::clone(&pool.shared);
            let worker = thread::Builder::new()
                .name(format!("cosim-step-{k}"))
                .spawn(move || work(&shared, k))?;
            pool.workers.push(worker);
        }
        Ok(pool)
    }

    /// Threads taking part in a round (the caller included).
    pub(crate) fn threads(&self) -> usize {
        self.workers.len() + 1
    }

    /// Call `f` once on every item, spread over the pool's threads; returns when all are done.
    /// A panic in `f` (on any thread) is raised here after the round has ended.
    pub(crate) fn for_each<T: Send>(&self, items: &mut [T], f: impl Fn(&mut T) + Sync) {
        let (n, threads) = (items.len(), self.threads());
        let block = |j: usize| j * n / threads..(j + 1) * n / threads;
        let chunk = (n / (threads * 8)).max(1);
        for (j, c) in self.cursors.iter().enumerate() {
            c.0.store(block(j).start, Ordering::Relaxed);
        }
        let base = Items(items.as_mut_ptr());
        let cursors = &self.cursors;
        let run = |me: usize| {
            // Its own block first, then the others' leftovers.
            for j in (0..threads).map(|d| (me + d) % threads) {
                let end = block(j).end;
                loop {
                    let start = cursors[j].0.fetch_add(chunk, Ordering::Relaxed);
                    if start >= end {
                        break;
                    }
                    for k in start..(start + chunk).min(end) {
                        // SAFETY: k < n is claimed by this thread alone (see `Items`); `items`
                        // outlives the round: `round` returns only when no thread is in it.
                        f(unsafe { &mut *base.at(k) });
                    }
                }
            }
        };
        self.round(&run);
    }

    /// Run `run` on the caller and on every worker that joins before the caller is done.
    fn round(&self, run: &(dyn Fn(usize) + Sync)) {
        let s = &*self.shared;
        let task = Task { run };
        // Only the lifetime is erased: workers use the pointer while `active` counts them, and
        // this function returns only after the round is retired and `active` is 0.
        let ptr = (&task as *const Task<'_>)
            .cast_mut()
            .cast::<Task<'static>>();
        s.task.store(ptr, Ordering::SeqCst);
        let generation = s.generation.fetch_add(1, Ordering::SeqCst) + 1;
        for w in &self.workers {
            w.thread().unpark();
        }
        let mine = panic::catch_unwind(AssertUnwindSafe(|| run(0)));
        // Late workers stay out; those inside finish their chunk (the items are all claimed).
        s.retired.store(generation, Ordering::SeqCst);
        let mut spins = 0u32;
        while s.active.load(Ordering::SeqCst) != 0 {
            spins += 1;
            if spins < 1 << 12 {
                std::hint::spin_loop();
            } else {
                thread::yield_now();
            }
        }
        let theirs = s.panicked.swap(false, Ordering::SeqCst);
        if let Err(p) = mine {
            panic::resume_unwind(p);
        }
        if theirs {
            panic!("a unit panicked in a worker thread");
        }
    }
}

/// A worker: wait for a round (spin, then park), join it unless retired, repeat until stopped.
fn work(s: &Shared, me: usize) {
    let mut seen = 0;
    loop {
        let since = Instant::now();
        let mut spins = 0u32;
        while s.generation.load(Ordering::SeqCst) == seen {
            if s.stop.load(Ordering::SeqCst) {
                return;
            }
            spins = spins.wrapping_add(1);
            if spins & 63 != 0 || since.elapsed() < SPIN {
                std::hint::spin_loop();
            } else {
                thread::park();
            }
        }
        s.active.fetch_add(1, Ordering::SeqCst);
        // Read after entering: the caller retires a round before it waits for `active`, so
        // either it sees us and waits, or we see the round retired and stay out.
        let generation = s.generation.load(Ordering::SeqCst);
        if s.retired.load(Ordering::SeqCst) != generation {
            // SAFETY: the round is not retired and we are counted in `active`: its task lives.
            let task = unsafe { &*s.task.load(Ordering::SeqCst) };
            if panic::catch_unwind(AssertUnwindSafe(|| (task.run)(me))).is_err() {
                s.panicked.store(true, Ordering::SeqCst);
            }
        }
        seen = generation;
        s.active.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Drop for Pool {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        for w in self.workers.drain(..) {
            w.thread().unpark();
            let _ = w.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Pool;

    #[test]
    fn every_item_once_on_any_number_of_threads() {
        for threads in [1, 2, 3, 8] {
            let pool = Pool::new(threads).unwrap();
            for n in [0, 1, 2, 5, 64, 1000] {
                for round in 0..50u64 {
                    let mut items: Vec<u64> = (0..n).collect();
                    pool.for_each(&mut items, |x| *x = *x * 3 + round);
                    let want: Vec<u64> = (0..n).map(|x| x * 3 + round).collect();
                    assert_eq!(items, want, "threads {threads}, n {n}");
                }
            }
        }
    }

    #[test]
    fn a_panic_reaches_the_caller_and_the_pool_goes_on() {
        let pool = Pool::new(2).unwrap();
        let mut items = vec![0u32; 100];
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.for_each(&mut items, |x| {
                if *x == 0 {
                    panic!("boom");
                }
            })
        }));
        assert!(r.is_err());
        let mut items = vec![1u32; 100];
        pool.for_each(&mut items, |x| *x += 1);
        assert!(items.iter().all(|&x| x == 2));
    }
}
