//! Particle shifting (beyond the paper; docs/decisions.md, "Particle shifting under strain").
//!
//! Xu, Stansby & Laurence (2009), J. Comput. Phys. 228, Eq. 23-24: after each step a fluid
//! particle moves, without changing its velocity, by
//! `delta r_i = -C alpha sum_j (l0 / r_ij)^2 e_ij` over its neighbours within re_grad (fluid,
//! wall and dummy alike), `e_ij = (r_j - r_i) / r_ij`, `alpha = u_max dt` the largest
//! particle travel of the step and `C` a coefficient. On a regular lattice the sum vanishes;
//! where neighbours crowd on one side the particle moves away from them, so a strained flow
//! keeps an even spacing instead of pairing up along its compressing direction.
//!
//! Where the neighbourhood is one-sided by nature the component across it is removed, as
//! Lind, Xu, Stansby & Rogers (2012) do at free surfaces: on a free-surface particle the
//! component along its neighbourhood's centroid direction, and on a particle with a fluid
//! neighbour of another phase the component along the direction to those neighbours (so no
//! shift carries a particle across a phase interface). A shift is capped at `max_shift l0`.

use super::kernel::Kernels;
use crate::particles::{Kind, Vector, View};

/// Particle shifting parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParticleShifting {
    /// Coefficient `C` of Xu et al. (2009) (dimensionless).
    pub coefficient: f64,
    /// Largest shift of one step, as a fraction of l0 (dimensionless).
    pub max_shift: f64,
}

impl Default for ParticleShifting {
    /// `C = 0.3`, at most `0.2 l0` a step: the Taylor-Green cell under MPS-HS-GC keeps its
    /// kinetic energy within 2 % over ten turnovers; with 0.1 and 0.2 it breaks down, with
    /// 0.4 and 0.5 it gains 5-10 % (docs/decisions.md, "Particle shifting under strain").
    fn default() -> Self {
        ParticleShifting {
            coefficient: 0.3,
            max_shift: 0.2,
        }
    }
}

/// Removes from `d` its component along `n` (any length; nothing if `n` is zero).
fn remove_along<const D: usize>(d: &mut Vector<D>, n: Vector<D>) {
    let m = n.norm();
    if m > 0.0 {
        let n = n / m;
        *d -= n * d.dot(&n);
    }
}

/// The shift (m) of fluid particle `i` of view `v` (zero for other kinds), `phase` each
/// particle's phase, `travel` the step's largest particle travel `u_max dt` (m).
pub fn shift<const D: usize>(
    i: usize,
    v: &View<D>,
    phase: &[u16],
    k: &Kernels,
    s: &ParticleShifting,
    travel: f64,
) -> Vector<D> {
    if v.kind[i] != Kind::Fluid {
        return Vector::zero();
    }
    let l0 = k.l0;
    let mut crowding = Vector::<D>::zero();
    let mut centroid = Vector::<D>::zero();
    let mut other_phase = Vector::<D>::zero();
    let mut interface = false;
    for q in v.pairs(i, k.grad.re) {
        let e = q.xij / q.r;
        crowding += e * (l0 * l0 / q.r2);
        centroid += e * q.w;
        if v.kind[q.j] == Kind::Fluid && phase[q.j] != phase[i] {
            other_phase += e * q.w;
            interface = true;
        }
    }
    let mut d = crowding * (-s.coefficient * travel);
    if v.free_surface[i] {
        remove_along(&mut d, centroid);
    }
    if interface {
        remove_along(&mut d, other_phase);
    }
    let m = d.norm();
    let cap = s.max_shift * l0;
    if m > cap {
        d = d * (cap / m);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numerics::kernel::weight;
    use crate::particles::view::Cloud;

    const L0: f64 = 0.01;

    /// A 9 x 9 lattice (spacing L0) with particle 40 (the centre) moved by `offset` (m).
    fn lattice(offset: Vector<2>) -> Vec<Vector<2>> {
        let mut pos: Vec<Vector<2>> = (0..81)
            .map(|n| Vector([(n % 9) as f64 * L0, (n / 9) as f64 * L0]))
            .collect();
        pos[40] += offset;
        pos
    }

    fn shift_of(cloud: &Cloud<2>, i: usize, phase: &[u16], travel: f64) -> Vector<2> {
        let k = Kernels::new::<2>(L0, 2.1, 3.1);
        shift(
            i,
            &cloud.view(),
            phase,
            &k,
            &ParticleShifting::default(),
            travel,
        )
    }

    fn cloud(pos: Vec<Vector<2>>) -> Cloud<2> {
        let n = pos.len();
        Cloud::new(pos, vec![Vector::zero(); n], vec![1000.0; n], 0.0, 3.1 * L0)
    }

    /// Unit vector of `sum_j e_ij w_ij` from particle `i` over `of` (within 2.1 L0).
    fn toward(pos: &[Vector<2>], i: usize, of: impl Fn(usize) -> bool) -> Vector<2> {
        let mut c = Vector::<2>::zero();
        for (j, x) in pos.iter().enumerate() {
            let r = (*x - pos[i]).norm();
            if j != i && of(j) && r < 2.1 * L0 {
                c += (*x - pos[i]) / r * weight(r, 2.1 * L0);
            }
        }
        c / c.norm()
    }

    /// On a regular lattice nothing moves; a particle pushed toward a neighbour moves back
    /// toward its lattice site, by an amount proportional to the step's travel and at most
    /// `max_shift l0`.
    #[test]
    fn a_lattice_stays_and_a_crowded_particle_moves_away() {
        let phase = vec![0u16; 81];
        let c = cloud(lattice(Vector::zero()));
        assert!(shift_of(&c, 40, &phase, 1e-3).norm() < 1e-15);
        let c = cloud(lattice(Vector([0.2 * L0, 0.0])));
        let d = shift_of(&c, 40, &phase, 1e-3);
        assert!(d[0] < 0.0, "{d:?}");
        assert!(d[1].abs() < 1e-12 * d[0].abs(), "{d:?}");
        let d2 = shift_of(&c, 40, &phase, 2e-3);
        assert!((d2[0] / d[0] - 2.0).abs() < 1e-12);
        let big = shift_of(&c, 40, &phase, 10.0);
        assert!((big.norm() - 0.2 * L0).abs() < 1e-15, "{big:?}");
    }

    /// Wall particles count as neighbours: a fluid particle two spacings from a wall column
    /// stays; without the wall column it moves away from the fluid side.
    #[test]
    fn walls_complete_the_neighbourhood() {
        let phase = vec![0u16; 81];
        let i = 4 * 9 + 2;
        let mut c = cloud(lattice(Vector::zero()));
        c.set_walls(|x| x[0] < 0.5 * L0);
        assert!(shift_of(&c, i, &phase, 1e-3).norm() < 1e-15);
        let pos: Vec<Vector<2>> = lattice(Vector::zero());
        let kept: Vec<Vector<2>> = pos.iter().copied().filter(|x| x[0] > 0.5 * L0).collect();
        let at = kept.iter().position(|x| *x == pos[i]).unwrap();
        let d = shift_of(&cloud(kept.clone()), at, &vec![0u16; kept.len()], 1e-3);
        assert!(d[0] < 0.0, "{d:?}");
    }

    /// On a free-surface particle only the component across its neighbourhood's centroid
    /// direction is kept, and at a phase interface only the component across the direction
    /// to the other phase; unflagged, or in one phase, the same particle is pushed along
    /// those directions too.
    #[test]
    fn no_shift_across_a_free_surface_or_a_phase_interface() {
        let mut pos: Vec<Vector<2>> = lattice(Vector::zero())
            .into_iter()
            .filter(|x| x[1] < 4.5 * L0)
            .collect();
        let top = pos
            .iter()
            .position(|x| (x[0] - 4.0 * L0).abs() < 1e-12 && (x[1] - 4.0 * L0).abs() < 1e-12)
            .unwrap();
        pos[top] += Vector([0.2 * L0, -0.1 * L0]);
        let phase = vec![0u16; pos.len()];
        let inward = toward(&pos, top, |_| true);
        let mut c = cloud(pos.clone());
        c.set_surface(|x| x[1] > 3.5 * L0);
        let d = shift_of(&c, top, &phase, 1e-3);
        assert!(
            d.norm() > 0.0 && d.dot(&inward).abs() < 1e-12 * d.norm(),
            "{d:?}"
        );
        let free = shift_of(&cloud(pos.clone()), top, &phase, 1e-3);
        assert!(free.dot(&inward) < -0.1 * free.norm(), "{free:?}");

        let mut pos = lattice(Vector::zero());
        pos[40] += Vector([0.2 * L0, -0.1 * L0]);
        let phase: Vec<u16> = pos.iter().map(|x| (x[1] > 4.5 * L0) as u16).collect();
        let other = toward(&pos, 40, |j| phase[j] == 1);
        let c = cloud(pos);
        let d = shift_of(&c, 40, &phase, 1e-3);
        assert!(
            d.norm() > 0.0 && d.dot(&other).abs() < 1e-12 * d.norm(),
            "{d:?}"
        );
        let one = shift_of(&c, 40, &[0u16; 81], 1e-3);
        assert!(one.dot(&other).abs() > 0.1 * one.norm(), "{one:?}");
    }
}
