//! A line on stderr at least every few seconds while a run works without a progress bar (set-up
//! of a large case, a long step, output to a log file): a run is never silent for long.

use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Longest silence before a line is written (s).
const SILENCE: f64 = 5.0;

struct State {
    /// What the run is doing, as the next line would say it.
    what: String,
    /// When a line was last written.
    last: Instant,
    /// Whether `what` changed since that line.
    fresh: bool,
    done: bool,
}

/// The writer thread and the status it writes.
pub struct Heartbeat {
    shared: Arc<(Mutex<State>, Condvar)>,
    thread: Option<JoinHandle<()>>,
}

impl Heartbeat {
    /// Starts writing `what` (and its later updates) after every `SILENCE` seconds of quiet.
    pub fn start(what: &str) -> Heartbeat {
        let shared = Arc::new((
            Mutex::new(State {
                what: what.to_string(),
                last: Instant::now(),
                fresh: true,
                done: false,
            }),
            Condvar::new(),
        ));
        let started = Instant::now();
        let s = Arc::clone(&shared);
        let thread = std::thread::spawn(move || {
            let (lock, cv) = &*s;
            let Ok(mut st) = lock.lock() else { return };
            loop {
                let Ok((g, _)) = cv.wait_timeout(st, Duration::from_millis(250)) else {
                    return;
                };
                st = g;
                if st.done {
                    return;
                }
                if st.last.elapsed().as_secs_f64() >= SILENCE {
                    let still = if st.fresh { "" } else { "still: " };
                    let secs = started.elapsed().as_secs_f64();
                    say_err!("[{secs:.0} s] {still}{}", st.what);
                    st.last = Instant::now();
                    st.fresh = false;
                }
            }
        });
        Heartbeat {
            shared,
            thread: Some(thread),
        }
    }

    /// Says what the run is doing now (written at the next beat).
    pub fn set(&self, what: String) {
        if let Ok(mut st) = self.shared.0.lock() {
            st.what = what;
            st.fresh = true;
        }
    }
}

impl Drop for Heartbeat {
    fn drop(&mut self) {
        if let Ok(mut st) = self.shared.0.lock() {
            st.done = true;
        }
        self.shared.1.notify_all();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
