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

/// Clears its flag when dropped (also on unwinding): a team no longer runs.
struct Released<'a>(&'a AtomicBool);

impl Drop for Released<'_> {
    fn drop(&mut self) {
        self.0.store(false, Ordering::Release);
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

pub use crate::parallel::Shared;

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
    use crate::parallel::tests::pool_of_two;

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
                    crate::parallel::with_helper(|| {
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
