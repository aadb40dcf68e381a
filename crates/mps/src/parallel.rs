//! The step's workers: a helper that stays with the step, and the step's parallel loops,
//! shared out in pieces between the stepping worker and its helper and ended by a spin on a
//! counter instead of a pool's `join` (docs/decisions.md, "Loops that end in a spin"). A
//! leaf: every folder may use it.
//!
//! rayon ends a loop's pieces with a `join`; the worker that waits there goes through the
//! pool's idle loop, one `sched_yield` a round. Here the stepping worker publishes the loop
//! in one slot, both workers claim pieces of it (guided: each a share of what is left, so
//! the pieces and their bounds are the same on every run), and the stepping worker spins
//! until the last piece is done, which takes at most one piece's time.

use std::cell::Cell;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU64, AtomicUsize, Ordering};
use std::sync::Mutex;

/// Idle rounds of a helper ([`with_helper`]) between two yields of its core (a few
/// milliseconds).
const HELPER_SPINS: u32 = 20_000;

/// Spins of the stepping worker, waiting for the helper's last piece, between two yields of
/// its core: on a loaded machine the helper may not be running.
const OWNER_SPINS: u32 = 4_000;

/// The fewest indices a piece of [`for_ranges`] holds (a particle's pair loop: 2-20 us).
const MIN_PIECE: usize = 16;

/// How many workers share a published loop: the stepping worker and its helper.
const WORKERS: usize = 2;

/// Bits of [`Slot::state`] that hold the next unclaimed index; the rest hold the loop's
/// generation.
const NEXT_BITS: u32 = 32;
const NEXT_MASK: u64 = (1 << NEXT_BITS) - 1;

/// A loop's body: called on disjoint ranges of its indices.
type Body<'a> = dyn Fn(Range<usize>) + Sync + 'a;

/// The one published loop of the process.
struct Slot {
    /// Generation (high bits) and the next unclaimed index (low bits; [`NEXT_MASK`] while
    /// the slot is being refilled).
    state: AtomicU64,
    /// The loop's number of indices.
    total: AtomicUsize,
    /// The fewest indices a piece holds.
    min: AtomicUsize,
    /// Indices finished.
    done: AtomicUsize,
    /// The body, a reference on the stepping worker's stack.
    body: AtomicPtr<&'static Body<'static>>,
    /// Set when a piece panicked on the helper.
    panicked: AtomicBool,
}

static SLOT: Slot = Slot {
    state: AtomicU64::new(0),
    total: AtomicUsize::new(0),
    min: AtomicUsize::new(1),
    done: AtomicUsize::new(0),
    body: AtomicPtr::new(std::ptr::null_mut()),
    panicked: AtomicBool::new(false),
};

thread_local! {
    /// Whether this thread runs work under the helper (and so may publish loops).
    static OWNS_HELPER: Cell<bool> = const { Cell::new(false) };

    /// Whether this thread is inside a piece of a loop: a loop inside runs on it alone.
    static IN_PIECE: Cell<bool> = const { Cell::new(false) };
}

/// End of the piece claimed at `next` of `total`: half of an even share of what is left,
/// at least `min` indices.
fn piece_end(total: usize, next: usize, min: usize) -> usize {
    let left = total - next;
    next + (left / (2 * WORKERS)).max(min).min(left)
}

impl Slot {
    /// Claims the next piece (at least `min` indices) of generation `gen` of `total`
    /// indices, if any is left.
    fn claim(&self, gen: u64, total: usize, min: usize) -> Option<Range<usize>> {
        let mut s = self.state.load(Ordering::Acquire);
        loop {
            let next = (s & NEXT_MASK) as usize;
            if s >> NEXT_BITS != gen || next >= total {
                return None;
            }
            let end = piece_end(total, next, min);
            let claimed = (gen << NEXT_BITS) | end as u64;
            match self
                .state
                .compare_exchange_weak(s, claimed, Ordering::AcqRel, Ordering::Acquire)
            {
                Ok(_) => return Some(next..end),
                Err(now) => s = now,
            }
        }
    }

    /// On a helper: runs one piece of the published loop, if one is left; whether it did.
    fn help_once(&self) -> bool {
        let s = self.state.load(Ordering::Acquire);
        if s & NEXT_MASK == NEXT_MASK {
            return false;
        }
        // A total and body of a later loop go with a state of a later generation (written
        // after the slot was closed): the claim below fails for them.
        let total = self.total.load(Ordering::Acquire);
        let min = self.min.load(Ordering::Acquire);
        let body = self.body.load(Ordering::Acquire);
        let Some(r) = self.claim(s >> NEXT_BITS, total, min) else {
            return false;
        };
        let len = r.len();
        let _counted = Counted(len);
        let _inside = Inside::enter();
        // SAFETY: the claim succeeded, so the loop of this generation has an unfinished
        // piece and its owner waits (in `run`) until the piece is counted: the body it
        // points to lives until then.
        unsafe { (**body)(r) };
        true
    }
}

/// Counts a helper's piece done when dropped, also when the piece panicked (then marking
/// the loop so the owner panics too instead of using a half-written result).
struct Counted(usize);

impl Drop for Counted {
    fn drop(&mut self) {
        if std::thread::panicking() {
            SLOT.panicked.store(true, Ordering::Relaxed);
        }
        SLOT.done.fetch_add(self.0, Ordering::Release);
    }
}

/// Marks this thread inside a piece until dropped.
struct Inside(bool);

impl Inside {
    fn enter() -> Inside {
        Inside(IN_PIECE.with(|c| c.replace(true)))
    }
}

impl Drop for Inside {
    fn drop(&mut self) {
        IN_PIECE.with(|c| c.set(self.0));
    }
}

/// On the owner, if its own piece panics: closes the loop and waits for the helper's
/// pieces (all claimed but the owner's own, `mine`), so none runs on a body that is being
/// unwound.
struct Closing {
    gen: u64,
    total: usize,
    mine: usize,
}

impl Drop for Closing {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            return;
        }
        let closed = (self.gen << NEXT_BITS) | NEXT_MASK;
        let before = SLOT.state.swap(closed, Ordering::AcqRel);
        let claimed = ((before & NEXT_MASK) as usize).min(self.total);
        wait_until_done(claimed - self.mine);
    }
}

/// Spins until the loop's finished count reaches `n`, yielding the core now and then.
fn wait_until_done(n: usize) {
    let mut spins = 0u32;
    while SLOT.done.load(Ordering::Acquire) < n {
        spins += 1;
        if spins.is_multiple_of(OWNER_SPINS) {
            std::thread::yield_now();
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Whether this thread may publish a loop: it runs the work under a helper, the helper is
/// the pool's only other worker, and it is not inside a piece.
fn publishes() -> bool {
    OWNS_HELPER.with(Cell::get)
        && rayon::current_num_threads() == WORKERS
        && !IN_PIECE.with(Cell::get)
}

/// Publishes `body` over `0..n` in pieces of at least `min`, runs pieces of it here, and
/// waits for the helper's.
fn run_published(n: usize, min: usize, body: &Body<'_>) {
    let s = SLOT.state.load(Ordering::Relaxed);
    let gen = ((s >> NEXT_BITS) + 1) & (u64::MAX >> NEXT_BITS);
    // Closed while refilled: a helper that read the old generation fails its claim.
    SLOT.state
        .store((gen << NEXT_BITS) | NEXT_MASK, Ordering::Relaxed);
    SLOT.done.store(0, Ordering::Relaxed);
    SLOT.total.store(n, Ordering::Release);
    SLOT.min.store(min, Ordering::Release);
    let body_ref: &Body<'_> = body;
    let ptr = &body_ref as *const &Body<'_> as *mut &'static Body<'static>;
    SLOT.body.store(ptr, Ordering::Release);
    SLOT.state.store(gen << NEXT_BITS, Ordering::Release);
    let mut closing = Closing {
        gen,
        total: n,
        mine: 0,
    };
    {
        let _inside = Inside::enter();
        while let Some(r) = SLOT.claim(gen, n, min) {
            closing.mine += r.len();
            body(r);
        }
    }
    SLOT.done.fetch_add(closing.mine, Ordering::Release);
    closing.mine = 0;
    wait_until_done(n);
    if SLOT.panicked.swap(false, Ordering::Relaxed) {
        panic!("a piece of a parallel loop panicked on the helper");
    }
}

/// Calls `body` on disjoint ranges that cover `0..n`, in parallel: under a helper on two
/// workers with the spin-ended loop, elsewhere on the current rayon pool (inside a piece,
/// on this thread alone). The ranges' bounds differ between these paths: what `body`
/// computes must not depend on them.
pub fn for_ranges(n: usize, body: impl Fn(Range<usize>) + Sync) {
    for_ranges_by(n, MIN_PIECE, body);
}

/// [`for_ranges`] with ranges of at least `min` indices (but the last): for loops whose
/// every index is a large piece of work (a chunk of particles).
pub fn for_ranges_by(n: usize, min: usize, body: impl Fn(Range<usize>) + Sync) {
    let min = min.max(1);
    if n == 0 {
        return;
    }
    if n <= min || IN_PIECE.with(Cell::get) {
        return body(0..n);
    }
    if publishes() && (n as u64) < NEXT_MASK {
        return run_published(n, min, &body);
    }
    if rayon::current_num_threads() < 2 {
        return body(0..n);
    }
    use rayon::prelude::*;
    let pieces = n.div_ceil(min);
    (0..pieces)
        .into_par_iter()
        .for_each(|p| body(p * min..((p + 1) * min).min(n)));
}

/// `out` filled with `f(i)` for `i` in `0..n`, in parallel ([`for_ranges`]); `out` keeps
/// its memory.
pub fn map_into<T: Send>(out: &mut Vec<T>, n: usize, f: impl Fn(usize) -> T + Sync) {
    out.clear();
    out.reserve(n);
    let dst = SendPtr(out.as_mut_ptr());
    for_ranges(n, |r| {
        for i in r {
            // SAFETY: the ranges are disjoint and within the reserved capacity.
            unsafe { dst.get().add(i).write(f(i)) };
        }
    });
    // SAFETY: every index below n was written exactly once above (a panic would have
    // unwound past this line, leaving the vector empty).
    unsafe { out.set_len(n) };
}

/// `f(i)` for `i` in `0..n` in a new vector, in parallel ([`for_ranges`]).
pub fn map<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let mut out = Vec::new();
    map_into(&mut out, n, f);
    out
}

/// `a` and `b` filled with the two parts of `f(i)` for `i` in `0..n`, in parallel; both keep
/// their memory.
pub fn unzip_into<A: Send, B: Send>(
    a: &mut Vec<A>,
    b: &mut Vec<B>,
    n: usize,
    f: impl Fn(usize) -> (A, B) + Sync,
) {
    a.clear();
    b.clear();
    a.reserve(n);
    b.reserve(n);
    let (pa, pb) = (SendPtr(a.as_mut_ptr()), SendPtr(b.as_mut_ptr()));
    for_ranges(n, |r| {
        for i in r {
            let (x, y) = f(i);
            // SAFETY: the ranges are disjoint and within the reserved capacities.
            unsafe {
                pa.get().add(i).write(x);
                pb.get().add(i).write(y);
            }
        }
    });
    // SAFETY: every index below n was written exactly once in both.
    unsafe {
        a.set_len(n);
        b.set_len(n);
    }
}

/// `f(i, &mut v[i])` for every index of `v`, in parallel ([`for_ranges`]).
pub fn for_each_mut<T: Send>(v: &mut [T], f: impl Fn(usize, &mut T) + Sync) {
    for_each_mut_by(v, MIN_PIECE, f);
}

/// [`for_each_mut`] in pieces of at least `min` indices (`usize::MAX`: on this thread).
pub fn for_each_mut_by<T: Send>(v: &mut [T], min: usize, f: impl Fn(usize, &mut T) + Sync) {
    let dst = SendPtr(v.as_mut_ptr());
    for_ranges_by(v.len(), min, |r| {
        for i in r {
            // SAFETY: the ranges are disjoint and within `v`.
            f(i, unsafe { &mut *dst.get().add(i) });
        }
    });
}

/// `f(scratch, i, &mut v[i])` for every index of `v`, in parallel, each piece with a
/// scratch of its own from `init`.
pub fn for_each_mut_init<T: Send, S>(
    v: &mut [T],
    init: impl Fn() -> S + Sync,
    f: impl Fn(&mut S, usize, &mut T) + Sync,
) {
    let dst = SendPtr(v.as_mut_ptr());
    for_ranges(v.len(), |r| {
        let mut scratch = init();
        for i in r {
            // SAFETY: the ranges are disjoint and within `v`.
            f(&mut scratch, i, unsafe { &mut *dst.get().add(i) });
        }
    });
}

/// `f(i, &mut a[i], &mut b[i])` for every index of `a` (as long as `b`), in parallel.
pub fn for_each_mut2<A: Send, B: Send>(
    a: &mut [A],
    b: &mut [B],
    f: impl Fn(usize, &mut A, &mut B) + Sync,
) {
    for_each_mut2_by(a, b, MIN_PIECE, f);
}

/// [`for_each_mut2`] in pieces of at least `min` indices (`usize::MAX`: on this thread).
pub fn for_each_mut2_by<A: Send, B: Send>(
    a: &mut [A],
    b: &mut [B],
    min: usize,
    f: impl Fn(usize, &mut A, &mut B) + Sync,
) {
    assert_eq!(a.len(), b.len());
    let (pa, pb) = (SendPtr(a.as_mut_ptr()), SendPtr(b.as_mut_ptr()));
    for_ranges_by(a.len(), min, |r| {
        for i in r {
            // SAFETY: the ranges are disjoint and within both slices.
            unsafe { f(i, &mut *pa.get().add(i), &mut *pb.get().add(i)) };
        }
    });
}

/// `op` over `f(i, &mut v[i])` for every index of `v`, from `identity`, in parallel (`op`
/// as for [`map_reduce`]).
pub fn for_each_mut_reduce<T: Send, R: Send + Sync + Copy>(
    v: &mut [T],
    identity: R,
    f: impl Fn(usize, &mut T) -> R + Sync,
    op: impl Fn(R, R) -> R + Sync,
) -> R {
    let dst = SendPtr(v.as_mut_ptr());
    ranges_reduce(v.len(), MIN_PIECE, identity, &op, |r| {
        r.fold(identity, |acc, i| {
            // SAFETY: the ranges are disjoint and within `v`.
            op(acc, f(i, unsafe { &mut *dst.get().add(i) }))
        })
    })
}

/// `op` over `f(i, &mut a[i], &mut b[i])` for every index of `a` (as long as `b`), from
/// `identity`, in parallel (`op` as for [`map_reduce`]).
pub fn for_each_mut2_reduce<A: Send, B: Send, R: Send + Sync + Copy>(
    a: &mut [A],
    b: &mut [B],
    identity: R,
    f: impl Fn(usize, &mut A, &mut B) -> R + Sync,
    op: impl Fn(R, R) -> R + Sync,
) -> R {
    assert_eq!(a.len(), b.len());
    let (pa, pb) = (SendPtr(a.as_mut_ptr()), SendPtr(b.as_mut_ptr()));
    ranges_reduce(a.len(), MIN_PIECE, identity, &op, |r| {
        r.fold(identity, |acc, i| {
            // SAFETY: the ranges are disjoint and within both slices.
            op(acc, unsafe {
                f(i, &mut *pa.get().add(i), &mut *pb.get().add(i))
            })
        })
    })
}

/// `op` over `f(i)` for `i` in `0..n`, from `identity`, in parallel. `op` must give the same
/// result in any order and grouping (a minimum, a maximum, an integer sum): the pieces are
/// combined in the order they finish.
pub fn map_reduce<R: Send + Sync + Copy>(
    n: usize,
    identity: R,
    f: impl Fn(usize) -> R + Sync,
    op: impl Fn(R, R) -> R + Sync,
) -> R {
    map_reduce_by(n, MIN_PIECE, identity, f, op)
}

/// [`map_reduce`] in pieces of at least `min` indices (`usize::MAX`: on this thread).
pub fn map_reduce_by<R: Send + Sync + Copy>(
    n: usize,
    min: usize,
    identity: R,
    f: impl Fn(usize) -> R + Sync,
    op: impl Fn(R, R) -> R + Sync,
) -> R {
    ranges_reduce(n, min, identity, &op, |r| {
        r.fold(identity, |a, i| op(a, f(i)))
    })
}

/// `op` over `piece(r)` for the ranges `r` of [`for_ranges_by`], from `identity`.
fn ranges_reduce<R: Send + Sync + Copy>(
    n: usize,
    min: usize,
    identity: R,
    op: &(impl Fn(R, R) -> R + Sync),
    piece: impl Fn(Range<usize>) -> R + Sync,
) -> R {
    let acc = Mutex::new(identity);
    for_ranges_by(n, min, |r| {
        let part = piece(r);
        let mut total = acc.lock().unwrap_or_else(|e| e.into_inner());
        *total = op(*total, part);
    });
    acc.into_inner().unwrap_or_else(|e| e.into_inner())
}

/// A vector the members of a team or the pieces of a loop share: each writes only where no
/// other reads or writes until the next barrier (or the loop's end).
pub struct Shared<T = f64> {
    ptr: *mut T,
    len: usize,
}

impl<T> Clone for Shared<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for Shared<T> {}

// SAFETY: members touch disjoint parts between barriers (the callers' contract), and the
// barrier orders their accesses.
unsafe impl<T: Send> Send for Shared<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for Shared<T> {}

impl<T> Shared<T> {
    /// Shares `v` for the lifetime of the borrow the caller keeps.
    pub fn new(v: &mut [T]) -> Shared<T> {
        Shared {
            ptr: v.as_mut_ptr(),
            len: v.len(),
        }
    }

    /// Entries `r`, to write.
    ///
    /// # Safety
    /// No other member touches `r` until the next barrier, and the vector outlives the use.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn part(&self, r: Range<usize>) -> &mut [T] {
        assert!(r.start <= r.end && r.end <= self.len);
        std::slice::from_raw_parts_mut(self.ptr.add(r.start), r.end - r.start)
    }

    /// The whole vector, to read.
    ///
    /// # Safety
    /// No member writes it until the next barrier.
    pub unsafe fn all(&self) -> &[T] {
        std::slice::from_raw_parts(self.ptr, self.len)
    }

    /// Entry `i`.
    ///
    /// # Safety
    /// No member writes entry `i` meanwhile.
    pub unsafe fn get(&self, i: usize) -> T
    where
        T: Copy,
    {
        assert!(i < self.len);
        *self.ptr.add(i)
    }

    /// Sets entry `i` to `x`.
    ///
    /// # Safety
    /// No other member reads or writes entry `i` until the next barrier.
    pub unsafe fn set(&self, i: usize, x: T) {
        assert!(i < self.len);
        *self.ptr.add(i) = x;
    }

    /// The raw pointer, for passes whose members write disjoint scattered entries.
    pub fn ptr(&self) -> *mut T {
        self.ptr
    }

    /// Its length.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// A raw pointer that pieces on other threads may use (each to its own indices).
struct SendPtr<T>(*mut T);

impl<T> SendPtr<T> {
    fn get(&self) -> *mut T {
        self.0
    }
}

// SAFETY: the pieces that share it write disjoint indices (the callers above).
unsafe impl<T: Send> Send for SendPtr<T> {}
// SAFETY: as above.
unsafe impl<T: Send> Sync for SendPtr<T> {}

/// Sets its flag when dropped (also on unwinding).
struct SetOnDrop<'a>(&'a AtomicBool);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// Clears the helper's flag when dropped (also on unwinding).
struct Released;

impl Drop for Released {
    fn drop(&mut self) {
        HELPER_RUNNING.store(false, Ordering::Release);
    }
}

/// Marks this thread as the helper's owner until dropped.
struct Owning;

impl Owning {
    fn enter() -> Owning {
        OWNS_HELPER.with(|c| c.set(true));
        Owning
    }
}

impl Drop for Owning {
    fn drop(&mut self) {
        OWNS_HELPER.with(|c| c.set(false));
    }
}

/// Whether a helper ([`with_helper`]) runs in this process. One at a time: a worker that
/// took a second work's helper while a piece of its own work waited below it on its stack
/// would wait for that work forever.
static HELPER_RUNNING: AtomicBool = AtomicBool::new(false);

/// Runs `work` on this worker of the pool while another worker waits for its parallel
/// loops' pieces in a spin loop, taking each as it appears (the loops of this module and
/// the pool's own), instead of going idle between them (where the pool's idle loop makes a
/// system call per round: docs/decisions.md, "A helper for the step"). On one thread,
/// outside a pool, or while another helper runs, `work` alone.
///
/// The helper is the first job `work`'s worker pushes, so it is stolen before any piece of
/// `work` can be: no other worker holds a piece of `work` below the helper on its stack.
/// `work`'s own worker may take it back while it waits (for a team's broadcast, say,
/// before the other worker woke up): there the helper ends at once.
pub fn with_helper<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    let Some(owner) = rayon::current_thread_index() else {
        return work();
    };
    if rayon::current_num_threads() < 2
        || HELPER_RUNNING
            .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
            .is_err()
    {
        return work();
    }
    let _running = Released;
    let done = AtomicBool::new(false);
    let (result, ()) = rayon::join(
        || {
            let _done = SetOnDrop(&done);
            let _owning = Owning::enter();
            work()
        },
        || {
            if rayon::current_thread_index() != Some(owner) {
                help_until(&done)
            }
        },
    );
    result
}

/// Takes the published loops' pieces and the pool's pending jobs (the other worker's
/// pieces, a team's broadcast) until `done`, spinning between them and yielding the core
/// only now and then.
fn help_until(done: &AtomicBool) {
    let mut idle = 0u32;
    while !done.load(Ordering::Acquire) {
        if SLOT.help_once() {
            idle = 0;
            continue;
        }
        match rayon::yield_now() {
            Some(rayon::Yield::Executed) => idle = 0,
            _ => {
                idle += 1;
                if idle.is_multiple_of(HELPER_SPINS) {
                    std::thread::yield_now();
                } else {
                    std::hint::spin_loop();
                }
            }
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rayon::prelude::*;

    /// A pool of two workers.
    pub(crate) fn pool_of_two() -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
    }

    /// The guided pieces cover `0..n` once each, shrink towards the end and hold at least
    /// [`MIN_PIECE`] indices but the last.
    #[test]
    fn guided_pieces_cover_the_range_once() {
        for n in [1, 15, 16, 17, 100, 7_000, 1_000_003] {
            let (mut next, mut sizes) = (0, Vec::new());
            while next < n {
                let end = piece_end(n, next, MIN_PIECE);
                sizes.push(end - next);
                next = end;
            }
            assert_eq!(next, n);
            assert!(sizes[..sizes.len() - 1].iter().all(|&s| s >= MIN_PIECE));
            assert!(sizes.windows(2).all(|w| w[1] <= w[0]), "{n}: {sizes:?}");
        }
    }

    /// Under a helper on two workers: every loop kind gives what a serial loop gives, the
    /// helper runs pieces of the published loops, a loop inside a piece runs there alone,
    /// and a loop outside any helper (on the pool, and on no pool) gives the same.
    #[test]
    fn loops_under_the_helper_give_the_serial_result() {
        let n = 50_000;
        let f = |i: usize| (i as f64).sqrt() + (i % 7) as f64;
        let serial: Vec<f64> = (0..n).map(f).collect();
        let check = || {
            let mut out = Vec::new();
            map_into(&mut out, n, f);
            assert_eq!(out, serial);
            let mut v = vec![0.0; n];
            let mut w = vec![0u64; n];
            for_each_mut(&mut v, |i, x| *x = f(i));
            assert_eq!(v, serial);
            for_each_mut2(&mut v, &mut w, |i, x, y| {
                *x += 1.0;
                *y = i as u64 % 5;
            });
            assert!(v.iter().zip(&serial).all(|(a, b)| *a == b + 1.0));
            let sum = map_reduce(n, 0u64, |i| w[i] + i as u64, |a, b| a + b);
            assert_eq!(sum, (0..n as u64).map(|i| i % 5 + i).sum::<u64>());
            let max = map_reduce(n, f64::NEG_INFINITY, f, f64::max);
            assert_eq!(
                max,
                serial.iter().copied().fold(f64::NEG_INFINITY, f64::max)
            );
            // Nested: the inner loop runs inside the piece.
            let nested = map_reduce(
                100,
                0u64,
                |i| map_reduce(i, 0u64, |j| j as u64, |a, b| a + b),
                |a, b| a + b,
            );
            assert_eq!(
                nested,
                (0..100u64).map(|i| i * i.saturating_sub(1) / 2).sum()
            );
        };
        check();
        let pool = pool_of_two();
        pool.install(check);
        let on_helper = AtomicUsize::new(0);
        // Another test's helper may hold the process's one: tried again then.
        let mut helped = false;
        for _ in 0..1000 {
            helped = pool.install(|| {
                with_helper(|| {
                    let me = rayon::current_thread_index();
                    if !OWNS_HELPER.with(Cell::get) {
                        return false;
                    }
                    check();
                    for _ in 0..200 {
                        for_ranges(64, |r| {
                            std::thread::sleep(std::time::Duration::from_micros(50));
                            if rayon::current_thread_index() != me {
                                on_helper.fetch_add(r.len(), Ordering::Relaxed);
                            }
                        });
                    }
                    true
                })
            });
            if helped {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert!(helped, "no helper could start");
        assert!(
            on_helper.load(Ordering::Relaxed) > 0,
            "no piece ran on the helper"
        );
    }

    /// Many short loops back to back under the helper, of lengths from 1 to 3 000 and with
    /// bodies that differ from loop to loop: every result is its own loop's (a helper that
    /// ran a piece of a finished loop with a later loop's body, or missed a piece, or ran
    /// one twice, shows as a wrong entry or a wrong count).
    #[test]
    fn back_to_back_loops_keep_their_own_bodies() {
        let pool = pool_of_two();
        let (mut bad, mut ran, helped) = (0, false, AtomicUsize::new(0));
        for _ in 0..1000 {
            let done = pool.install(|| {
                with_helper(|| {
                    if !OWNS_HELPER.with(Cell::get) {
                        return None;
                    }
                    let (mut out, mut bad) = (Vec::new(), 0);
                    let me = rayon::current_thread_index();
                    let mut seed = 12345u64;
                    for round in 0..20_000u64 {
                        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                        let n = (seed >> 33) as usize % 3000 + 1;
                        map_into(&mut out, n, |i| i as u64 * 7 + round);
                        bad += (0..n).filter(|&i| out[i] != i as u64 * 7 + round).count();
                        let count = AtomicUsize::new(0);
                        for_ranges(n, |r| {
                            count.fetch_add(r.len(), Ordering::Relaxed);
                            if rayon::current_thread_index() != me {
                                helped.fetch_add(1, Ordering::Relaxed);
                            }
                        });
                        bad += (count.into_inner() != n) as usize;
                    }
                    Some(bad)
                })
            });
            if let Some(b) = done {
                (bad, ran) = (b, true);
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert!(ran, "no helper could start");
        assert!(helped.into_inner() > 0, "no piece ran on the helper");
        assert_eq!(bad, 0);
    }

    /// Work under a helper gives its result with its pool loops done on both workers
    /// (the helper takes their pieces), a second helper inside runs its work alone, and a
    /// panic in the work (or in a piece of a published loop) ends the helper and reaches
    /// the caller instead of hanging.
    #[test]
    fn the_helper_takes_the_pieces_and_stops_with_the_work() {
        let pool = pool_of_two();
        let other = AtomicUsize::new(0);
        let sum = pool.install(|| {
            with_helper(|| {
                let me = rayon::current_thread_index();
                let inner = with_helper(|| 7u64);
                // Pieces of a millisecond: long enough for the other worker to wake up.
                let s: u64 = (0..200usize)
                    .into_par_iter()
                    .with_max_len(1)
                    .map(|i| {
                        std::thread::sleep(std::time::Duration::from_millis(1));
                        if rayon::current_thread_index() != me {
                            other.fetch_add(1, Ordering::Relaxed);
                        }
                        (i % 3) as u64
                    })
                    .sum();
                s + inner
            })
        });
        assert_eq!(sum, (0..200u64).map(|i| i % 3).sum::<u64>() + 7);
        assert!(
            other.load(Ordering::Relaxed) > 0,
            "no piece ran on the helper"
        );
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| with_helper(|| panic!("the work fails")))
        }));
        assert!(caught.is_err());
        for _ in 0..20 {
            let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                pool.install(|| {
                    with_helper(|| {
                        for_ranges(10_000, |r| {
                            std::thread::sleep(std::time::Duration::from_micros(20));
                            assert!(!r.contains(&5_000), "a piece fails");
                        })
                    })
                })
            }));
            assert!(caught.is_err());
        }
        // The flag is free again: a later helper runs.
        assert!(!HELPER_RUNNING.load(Ordering::Acquire));
        assert!(!OWNS_HELPER.with(Cell::get));
    }
}
