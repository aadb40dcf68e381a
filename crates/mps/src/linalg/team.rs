//! A team of the pool's threads kept together for one whole solve, meeting at spin barriers
//! instead of being handed each short pass by the pool (docs/decisions.md, "MIC(0) in the
//! twisted numbering"). A CG iteration of a few thousand unknowns lasts about 100 us: a
//! worker woken for each of its passes sleeps between them and costs more than it brings.

use super::sparse::{row_dot, CsrMatrix};
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Spins of a waiting member before it yields its core (about 0.1 ms on the 2-core test
/// machine; a yield costs 1 us of system time there): on a loaded machine the other
/// member may not be running.
const SPINS_BEFORE_YIELD: u32 = 4000;

/// The meeting point of a team.
struct Barrier {
    size: usize,
    arrived: AtomicUsize,
    generation: AtomicUsize,
    /// Set when a member panicked: the others stop waiting for it.
    broken: AtomicBool,
}

/// One member of a running team: its index in `0..size` and the team's barrier.
pub struct Member<'a> {
    /// This member's index.
    pub index: usize,
    /// How many members the team has.
    pub size: usize,
    barrier: &'a Barrier,
}

impl Member<'_> {
    /// Waits until every member has arrived here; what any member wrote before it is
    /// visible to all after it.
    pub fn wait(&self) {
        let b = self.barrier;
        if b.size == 1 {
            return;
        }
        let gen = b.generation.load(Ordering::Acquire);
        if b.arrived.fetch_add(1, Ordering::AcqRel) + 1 == b.size {
            b.arrived.store(0, Ordering::Relaxed);
            b.generation.store(gen + 1, Ordering::Release);
            return;
        }
        let mut spins = 0;
        while b.generation.load(Ordering::Acquire) == gen {
            if b.broken.load(Ordering::Relaxed) {
                panic!("a member of the solver's team panicked");
            }
            if spins < SPINS_BEFORE_YIELD {
                std::hint::spin_loop();
                spins += 1;
            } else {
                std::thread::yield_now();
            }
        }
    }

    /// This member's share of `0..blocks` (contiguous, in member order).
    pub fn share(&self, blocks: usize) -> Range<usize> {
        (self.index * blocks / self.size)..((self.index + 1) * blocks / self.size)
    }
}

/// Marks the barrier broken if its member unwinds.
struct Guard<'a>(&'a Barrier);

impl Drop for Guard<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            self.0.broken.store(true, Ordering::Relaxed);
        }
    }
}

/// Whether a team is running in this process. Two teams broadcast into one pool at once
/// could each hold one worker while waiting for the other's, so a second team runs on its
/// calling thread alone (the results do not depend on the team's size).
static TEAM_RUNNING: AtomicBool = AtomicBool::new(false);

/// Waits (up to a second) until no team runs in this process, so that a test's next team
/// is likely to get its members.
#[cfg(test)]
pub(crate) fn wait_for_no_team() {
    for _ in 0..1000 {
        if !TEAM_RUNNING.load(Ordering::Acquire) {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

/// Idle rounds of a helper ([`with_helper`]) between two yields of its core (a few
/// milliseconds).
const HELPER_SPINS: u32 = 20_000;

/// Sets its flag when dropped (also on unwinding).
struct SetOnDrop<'a>(&'a AtomicBool);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Release);
    }
}

/// Clears its flag when dropped (also on unwinding): a team or helper no longer runs.
struct Released<'a>(&'a AtomicBool);

impl Drop for Released<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::Release);
    }
}

/// Whether a helper ([`with_helper`]) runs in this process. One at a time: a worker that
/// took a second work's helper while a piece of its own work waited below it on its stack
/// would wait for that work forever.
static HELPER_RUNNING: AtomicBool = AtomicBool::new(false);

/// Runs `work` on this worker of the pool while another worker waits for its parallel
/// loops' pieces in a spin loop, taking each as it appears, instead of going idle between
/// them (where the pool's idle loop makes a system call per round: docs/decisions.md,
/// "A helper for the step"). On one thread, outside a pool, or while another helper runs,
/// `work` alone.
///
/// The helper is the first job `work`'s worker pushes, so it is stolen before any piece of
/// `work` can be: no other worker holds a piece of `work` below the helper on its stack.
/// `work`'s own worker may take it back while it waits (for a team's broadcast, say,
/// before the other worker woke up): there the helper ends at once.
pub fn with_helper<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    if rayon::current_num_threads() < 2
        || rayon::current_thread_index().is_none()
        || HELPER_RUNNING
            .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
            .is_err()
    {
        return work();
    }
    let _running = Released(&HELPER_RUNNING);
    let done = AtomicBool::new(false);
    let owner = rayon::current_thread_index();
    let (result, ()) = rayon::join(
        || {
            let _done = SetOnDrop(&done);
            work()
        },
        || {
            if rayon::current_thread_index() != owner {
                help_until(&done)
            }
        },
    );
    result
}

/// Takes the pool's pending jobs (the other worker's pieces, a team's broadcast) until
/// `done`, spinning between them and yielding the core only now and then.
fn help_until(done: &AtomicBool) {
    let mut idle = 0u32;
    while !done.load(Ordering::Acquire) {
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

/// Runs `work` on a team of `size` members: on this thread alone for 1 or while another
/// team runs, else on the first `size` threads of the current rayon pool (at most its
/// size), all at once.
pub fn run_team(size: usize, work: impl Fn(&Member) + Sync) {
    let mut size = size.clamp(1, rayon::current_num_threads());
    let _running = match size > 1
        && TEAM_RUNNING
            .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
            .is_ok()
    {
        true => Some(Released(&TEAM_RUNNING)),
        false => {
            size = 1;
            None
        }
    };
    let barrier = Barrier {
        size,
        arrived: AtomicUsize::new(0),
        generation: AtomicUsize::new(0),
        broken: AtomicBool::new(false),
    };
    let member = |index| {
        let _guard = Guard(&barrier);
        work(&Member {
            index,
            size,
            barrier: &barrier,
        })
    };
    if size == 1 {
        return member(0);
    }
    rayon::broadcast(|ctx| {
        if ctx.index() < size {
            member(ctx.index())
        }
    });
}

/// A vector the members of a team share: each writes only where no other member reads or
/// writes until the next barrier.
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

/// Rows per block of a team's passes; dot products are summed block by block in block
/// order, whatever the team's size, so every team gives the same sums.
pub(crate) const BLOCK: usize = 256;

/// Rows of blocks `blocks` of a system of `n` rows.
pub(crate) fn rows_of(blocks: &Range<usize>, n: usize) -> Range<usize> {
    (blocks.start * BLOCK).min(n)..(blocks.end * BLOCK).min(n)
}

/// Each of the blocks `mine`'s rows of a system of `n` rows, with the block's place.
pub(crate) fn blocks_of(
    mine: &Range<usize>,
    n: usize,
) -> impl Iterator<Item = (usize, Range<usize>)> {
    mine.clone()
        .enumerate()
        .map(move |(k, blk)| (k, rows_of(&(blk..blk + 1), n)))
}

/// The sum of a shared partial-sum vector, in block order.
///
/// # Safety
/// Called between barriers, with every block written.
pub(crate) unsafe fn total(parts: Shared) -> f64 {
    parts.all().iter().sum()
}

/// `r = b - A x` on the own rows of blocks `mine`, `r . r` in the blocks' partial sums
/// `rr` and, with `bb`, `b . b` in those.
///
/// # Safety
/// No member writes `x` meanwhile, and the own rows of `r` and own blocks of the sums are
/// this member's alone until the next barrier.
pub(crate) unsafe fn residual(
    a: &CsrMatrix,
    b: &[f64],
    (x, r): (Shared, Shared),
    (bb, rr): (Option<Shared>, Shared),
    mine: &Range<usize>,
) {
    let n = b.len();
    let own = rows_of(mine, n);
    let xs = x.all();
    let r = r.part(own.clone());
    let mut bb_own = bb.as_ref().map(|s| s.part(mine.clone()));
    let rr_own = rr.part(mine.clone());
    for (k, rows) in blocks_of(mine, n) {
        let (mut bsum, mut rsum) = (0.0, 0.0);
        for i in rows {
            let (c, w) = a.row(i);
            let ri = b[i] - row_dot(c, w, xs);
            r[i - own.start] = ri;
            bsum += b[i] * b[i];
            rsum += ri * ri;
        }
        if let Some(bb) = bb_own.as_mut() {
            bb[k] = bsum;
        }
        rr_own[k] = rsum;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pool of two workers.
    fn pool_of_two() -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
    }

    /// Two members each fill their half, meet, and then each reads the other's half: every
    /// round sees the other's writes of that round (a broken barrier shows a stale value).
    /// A team started while another test's team runs has one member: tried again then.
    #[test]
    fn members_see_each_others_writes_after_the_barrier() {
        let pool = pool_of_two();
        let mut v = vec![0.0; 2];
        let shared = Shared::new(&mut v);
        let errors = AtomicUsize::new(0);
        let mut pairs = 0;
        for _ in 0..2000 {
            let size = AtomicUsize::new(0);
            pool.install(|| {
                run_team(2, |m| {
                    size.store(m.size, Ordering::Relaxed);
                    if m.size != 2 {
                        return;
                    }
                    for round in 1..=2000 {
                        // SAFETY: each member writes its own entry between barriers.
                        unsafe { shared.part(m.index..m.index + 1)[0] = round as f64 };
                        m.wait();
                        // SAFETY: nobody writes until the next barrier.
                        let other = unsafe { shared.all()[1 - m.index] };
                        if other != round as f64 {
                            errors.fetch_add(1, Ordering::Relaxed);
                        }
                        m.wait();
                    }
                })
            });
            if size.load(Ordering::Relaxed) == 2 {
                pairs += 1;
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        assert_eq!(pairs, 1, "no team of two could start");
        assert_eq!(errors.load(Ordering::Relaxed), 0);
        assert_eq!(v, vec![2000.0, 2000.0]);
    }

    /// Teams started at once from many threads into one pool finish, each member meeting
    /// its own team's at the barrier (a smoke test: the hang that [`TEAM_RUNNING`] rules
    /// out needs two broadcasts queued in opposite orders on the two workers, which this
    /// rarely produces).
    #[test]
    fn teams_started_at_once_do_not_wait_on_each_other() {
        let pool = pool_of_two();
        let done = AtomicUsize::new(0);
        std::thread::scope(|scope| {
            for _ in 0..6 {
                scope.spawn(|| {
                    for _ in 0..200 {
                        let sum = AtomicUsize::new(0);
                        pool.install(|| {
                            run_team(2, |m| {
                                sum.fetch_add(m.index + 1, Ordering::Relaxed);
                                m.wait();
                                let all = if m.size == 2 { 3 } else { 1 };
                                assert_eq!(sum.load(Ordering::Relaxed), all);
                            })
                        });
                        done.fetch_add(1, Ordering::Relaxed);
                    }
                });
            }
        });
        assert_eq!(done.load(Ordering::Relaxed), 1200);
    }

    #[test]
    fn shares_cover_the_blocks_once() {
        let b = Barrier {
            size: 3,
            arrived: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            broken: AtomicBool::new(false),
        };
        let parts: Vec<Range<usize>> = (0..3)
            .map(|index| {
                Member {
                    index,
                    size: 3,
                    barrier: &b,
                }
                .share(10)
            })
            .collect();
        assert_eq!(parts, vec![0..3, 3..6, 6..10]);
    }

    /// Work under a helper gives its result with its parallel loops done on both workers
    /// (the helper takes their pieces), a team started inside it gets its members, a second
    /// helper inside runs its work alone, and a panic in the work ends the helper and
    /// reaches the caller instead of hanging.
    #[test]
    fn the_helper_takes_the_pieces_and_stops_with_the_work() {
        use rayon::prelude::*;
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
        // The flag is free again: a later helper runs.
        assert!(!HELPER_RUNNING.load(Ordering::Acquire));
    }

    /// The stepping worker that takes its own helper back while it waits for a team (the
    /// other worker still asleep) goes on: a helper there would wait for the step it sits
    /// in. Run on a watchdog: a hang fails the test.
    #[test]
    fn a_team_inside_the_helper_s_work_does_not_hang() {
        let (send, receive) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let pool = pool_of_two();
            let mut met = 0;
            for _ in 0..50 {
                // Long enough for the other worker to fall asleep.
                std::thread::sleep(std::time::Duration::from_millis(3));
                met += pool.install(|| {
                    with_helper(|| {
                        let n = AtomicUsize::new(0);
                        run_team(2, |m| {
                            m.wait();
                            n.fetch_add(1, Ordering::Relaxed);
                        });
                        n.into_inner()
                    })
                });
            }
            send.send(met).unwrap();
        });
        let met = receive
            .recv_timeout(std::time::Duration::from_secs(60))
            .expect("the work under the helper hung");
        assert!(met >= 50, "{met}");
    }
}
