//! Breakdown: when a run stops being physical (cases.md, "Breakdown"), and the checks of a
//! new state that decide it.

use crate::parallel;
use crate::particles::{Kind, Particles, Vector};
use std::fmt;

/// Why a run broke down.
#[derive(Clone, Debug, PartialEq)]
pub enum BreakdownReason {
    /// A NaN or infinity appeared.
    NotFinite,
    /// The PPE solver did not converge.
    SolverDiverged {
        /// Iterations taken.
        iterations: usize,
        /// Relative residual reached.
        residual: f64,
    },
    /// A particle left the domain.
    LeftDomain,
    /// Two particles came closer than the stated fraction of l0.
    Penetration {
        /// Closest distance / l0.
        distance_l0: f64,
    },
    /// The largest speed passed its bound.
    SpeedBlowUp {
        /// Speed reached (m/s).
        speed: f64,
        /// Bound (m/s).
        bound: f64,
    },
    /// The Courant time step fell below its floor.
    TimeStepCollapse {
        /// The step the Courant limit asked for (s).
        dt: f64,
    },
    /// Another process of a distributed run broke down in this step.
    Elsewhere,
    /// What a process of a distributed run found (its reason, in words).
    OnProcess {
        /// The process's rank.
        rank: usize,
        /// Its reason, as [`BreakdownReason`]'s text.
        why: String,
    },
    /// A distributed run could not go on (a particle exchange failed, or what it does not do
    /// yet).
    Distributed(String),
}

/// A breakdown: when, why, and which particles (ids) were involved.
#[derive(Clone, Debug, PartialEq)]
pub struct Breakdown {
    /// Simulated time of the last good state (s).
    pub time: f64,
    /// Step number that failed.
    pub step: u64,
    /// The reason.
    pub reason: BreakdownReason,
    /// Ids of the particles involved (at most a few).
    pub particles: Vec<u32>,
}

/// A failed step: the reason and the ids of the particles involved.
#[derive(Clone, Debug, PartialEq)]
pub struct Failure {
    /// The reason.
    pub reason: BreakdownReason,
    /// Ids of the particles involved, at most a few.
    pub particles: Vec<u32>,
}

impl From<BreakdownReason> for Failure {
    fn from(reason: BreakdownReason) -> Self {
        Failure {
            reason,
            particles: Vec::new(),
        }
    }
}

impl fmt::Display for Breakdown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "breakdown at t = {:.6} s (step {}): {}",
            self.time, self.step, self.reason
        )
    }
}

impl fmt::Display for BreakdownReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let why = match self {
            BreakdownReason::NotFinite => "NaN or infinity in the particle state".to_string(),
            BreakdownReason::SolverDiverged {
                iterations,
                residual,
            } => format!(
                "pressure solver did not converge ({iterations} iterations, residual {residual:.2e})"
            ),
            BreakdownReason::LeftDomain => {
                "a particle left the domain (domain.outflow = \"remove\" lets it leave)".to_string()
            }
            BreakdownReason::Penetration { distance_l0 } => {
                format!("particles interpenetrated (pair at {distance_l0:.3} l0)")
            }
            BreakdownReason::SpeedBlowUp { speed, bound } => {
                format!("speed blew up ({speed:.3e} m/s > bound {bound:.3e} m/s)")
            }
            BreakdownReason::TimeStepCollapse { dt } => {
                format!("time step collapsed (dt = {dt:.3e} s)")
            }
            BreakdownReason::Elsewhere => "another process of the run broke down".to_string(),
            BreakdownReason::Distributed(why) => format!("distributed run: {why}"),
            BreakdownReason::OnProcess { rank, why } => format!("{why} (on process {rank})"),
        };
        f.write_str(&why)
    }
}

/// The limits a new state is checked against.
#[derive(Clone, Copy, Debug)]
pub struct Limits<const D: usize> {
    /// Fluid particles beyond this box have left the domain (m).
    pub lo: Vector<D>,
    /// Upper corner of that box (m).
    pub hi: Vector<D>,
    /// Closest allowed pair (m).
    pub min_pair: f64,
    /// Particle spacing (m), the unit of reported distances.
    pub l0: f64,
    /// Largest allowed fluid speed (m/s).
    pub max_speed: f64,
    /// Fluid beyond the box is removed after the step (`domain.outflow = "remove"`), not a
    /// failure.
    pub outflow: bool,
}

/// At most this many particles are named in a failure.
const NAMED: usize = 8;

/// Ids of the first few of the particles `0 .. n` matching `pred`.
fn first_matching<const D: usize>(
    p: &Particles<D>,
    n: usize,
    pred: impl Fn(usize) -> bool,
) -> Vec<u32> {
    (0..n)
        .filter(|&i| pred(i))
        .take(NAMED)
        .map(|i| p.id[i])
        .collect()
}

/// Checks a new state (`pos`, `vel`, `pressure` over the first particles of `p`, the closest pair
/// `min_pair` in m) against the limits; returns the largest fluid speed (m/s).
pub fn check_state<const D: usize>(
    p: &Particles<D>,
    pos: &[Vector<D>],
    vel: &[Vector<D>],
    pressure: &[f64],
    min_pair: f64,
    lim: &Limits<D>,
) -> Result<f64, Failure> {
    let n = pos.len();
    let finite = |i: usize| pos[i].is_finite() && vel[i].is_finite() && pressure[i].is_finite();
    let outside = |i: usize| {
        p.kind[i] == Kind::Fluid && (0..D).any(|k| pos[i][k] < lim.lo[k] || pos[i][k] > lim.hi[k])
    };
    // One pass: whether every entry is finite, whether a fluid particle left the box, and
    // the largest fluid speed (each a breakdown reason, tested in this order below).
    let flags = |i: usize| {
        let u = match p.kind[i] == Kind::Fluid {
            true => vel[i].norm(),
            false => 0.0,
        };
        (finite(i), outside(i), u)
    };
    let (all_finite, any_outside, umax) =
        parallel::map_reduce(n, (true, false, 0.0), flags, |a, b| {
            (a.0 && b.0, a.1 || b.1, f64::max(a.2, b.2))
        });
    if !all_finite {
        return Err(Failure {
            reason: BreakdownReason::NotFinite,
            particles: first_matching(p, n, |i| !finite(i)),
        });
    }
    if !lim.outflow && any_outside {
        return Err(Failure {
            reason: BreakdownReason::LeftDomain,
            particles: first_matching(p, n, outside),
        });
    }
    if min_pair < lim.min_pair {
        return Err(BreakdownReason::Penetration {
            distance_l0: min_pair / lim.l0,
        }
        .into());
    }
    if umax > lim.max_speed {
        let bound = lim.max_speed;
        return Err(Failure {
            reason: BreakdownReason::SpeedBlowUp { speed: umax, bound },
            particles: first_matching(p, n, |i| vel[i].norm() > bound),
        });
    }
    Ok(umax)
}
