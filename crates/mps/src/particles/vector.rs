//! Small fixed-size vectors and matrices, generic over the space dimension `D`.
//!
//! The solver is written once for any `D`; 2D (`D = 2`) ships now and 3D is a later
//! instantiation of the same code.

use serde::de::{self, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;
use std::ops::{Add, AddAssign, Div, Index, IndexMut, Mul, Neg, Sub, SubAssign};

/// A point or vector in `D`-dimensional space (metres, or m/s for velocities).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vector<const D: usize>(pub [f64; D]);

impl<const D: usize> Default for Vector<D> {
    fn default() -> Self {
        Self::zero()
    }
}

impl<const D: usize> Vector<D> {
    /// The zero vector.
    #[inline]
    pub const fn zero() -> Self {
        Vector([0.0; D])
    }
    /// Builds a vector from a slice of exactly `D` components; `None` if the length differs.
    pub fn from_slice(s: &[f64]) -> Option<Self> {
        if s.len() != D {
            return None;
        }
        let mut v = [0.0; D];
        v.copy_from_slice(s);
        Some(Vector(v))
    }
    /// Scalar product.
    #[inline]
    pub fn dot(&self, o: &Self) -> f64 {
        let mut s = 0.0;
        for k in 0..D {
            s += self.0[k] * o.0[k];
        }
        s
    }
    /// Squared Euclidean length.
    #[inline]
    pub fn norm2(&self) -> f64 {
        self.dot(self)
    }
    /// Euclidean length.
    #[inline]
    pub fn norm(&self) -> f64 {
        self.norm2().sqrt()
    }
    /// True when every component is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|c| c.is_finite())
    }
    /// Component-wise minimum.
    pub fn min(&self, o: &Self) -> Self {
        let mut v = *self;
        for k in 0..D {
            v.0[k] = v.0[k].min(o.0[k]);
        }
        v
    }
    /// Component-wise maximum.
    pub fn max(&self, o: &Self) -> Self {
        let mut v = *self;
        for k in 0..D {
            v.0[k] = v.0[k].max(o.0[k]);
        }
        v
    }
    /// Outer product `self ⊗ o`.
    #[inline]
    pub fn outer(&self, o: &Self) -> Matrix<D> {
        let mut m = Matrix::zero();
        for a in 0..D {
            for b in 0..D {
                m.0[a][b] = self.0[a] * o.0[b];
            }
        }
        m
    }
    /// The z component of the cross product of the first two components (2D "cross").
    #[inline]
    pub fn cross_z(&self, o: &Self) -> f64 {
        self.0[0] * o.0[1] - self.0[1] * o.0[0]
    }
    /// The cross product as a 3-vector, a 2D vector taken in the plane z = 0.
    #[inline]
    pub fn cross3(&self, o: &Self) -> [f64; 3] {
        let (a, b) = (self.padded(), o.padded());
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }
    /// The components padded with zeros to three.
    #[inline]
    pub fn padded(&self) -> [f64; 3] {
        let mut v = [0.0; 3];
        for (k, c) in self.0.iter().take(3).enumerate() {
            v[k] = *c;
        }
        v
    }
}

impl<const D: usize> Index<usize> for Vector<D> {
    type Output = f64;
    #[inline]
    fn index(&self, k: usize) -> &f64 {
        &self.0[k]
    }
}
impl<const D: usize> IndexMut<usize> for Vector<D> {
    #[inline]
    fn index_mut(&mut self, k: usize) -> &mut f64 {
        &mut self.0[k]
    }
}

macro_rules! componentwise {
    ($tr:ident, $f:ident, $op:tt, $tra:ident, $fa:ident, $opa:tt) => {
        impl<const D: usize> $tr for Vector<D> {
            type Output = Self;
            #[inline]
            fn $f(mut self, o: Self) -> Self {
                for k in 0..D {
                    self.0[k] $opa o.0[k];
                }
                self
            }
        }
        impl<const D: usize> $tra for Vector<D> {
            #[inline]
            fn $fa(&mut self, o: Self) {
                for k in 0..D {
                    self.0[k] $opa o.0[k];
                }
            }
        }
    };
}
componentwise!(Add, add, +, AddAssign, add_assign, +=);
componentwise!(Sub, sub, -, SubAssign, sub_assign, -=);

impl<const D: usize> Mul<f64> for Vector<D> {
    type Output = Self;
    #[inline]
    fn mul(mut self, s: f64) -> Self {
        for k in 0..D {
            self.0[k] *= s;
        }
        self
    }
}
impl<const D: usize> Mul<Vector<D>> for f64 {
    type Output = Vector<D>;
    #[inline]
    fn mul(self, v: Vector<D>) -> Vector<D> {
        v * self
    }
}
impl<const D: usize> Div<f64> for Vector<D> {
    type Output = Self;
    #[inline]
    fn div(self, s: f64) -> Self {
        self * (1.0 / s)
    }
}
impl<const D: usize> Neg for Vector<D> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        self * -1.0
    }
}

/// Serialised as a tuple of `D` numbers (checkpoints).
impl<const D: usize> Serialize for Vector<D> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(D)?;
        for c in &self.0 {
            t.serialize_element(c)?;
        }
        t.end()
    }
}

impl<'de, const D: usize> Deserialize<'de> for Vector<D> {
    fn deserialize<De: Deserializer<'de>>(d: De) -> Result<Self, De::Error> {
        struct Components<const D: usize>;
        impl<'de, const D: usize> Visitor<'de> for Components<D> {
            type Value = Vector<D>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "{D} numbers")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut a: A) -> Result<Vector<D>, A::Error> {
                let mut v = [0.0; D];
                for (k, c) in v.iter_mut().enumerate() {
                    *c = a
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(k, &self))?;
                }
                Ok(Vector(v))
            }
        }
        d.deserialize_tuple(D, Components::<D>)
    }
}

/// A `D x D` matrix (row-major), used for the gradient-correction tensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Matrix<const D: usize>(pub [[f64; D]; D]);

impl<const D: usize> Matrix<D> {
    /// The zero matrix.
    #[inline]
    pub const fn zero() -> Self {
        Matrix([[0.0; D]; D])
    }
    /// `s` times the identity.
    pub fn scaled_identity(s: f64) -> Self {
        let mut m = Self::zero();
        for k in 0..D {
            m.0[k][k] = s;
        }
        m
    }
    /// Matrix-vector product.
    #[inline]
    pub fn mul_vec(&self, v: &Vector<D>) -> Vector<D> {
        let mut out = Vector::zero();
        for a in 0..D {
            let mut s = 0.0;
            for b in 0..D {
                s += self.0[a][b] * v.0[b];
            }
            out.0[a] = s;
        }
        out
    }
    /// Adds `s * m` in place.
    #[inline]
    pub fn add_scaled(&mut self, m: &Matrix<D>, s: f64) {
        for a in 0..D {
            for b in 0..D {
                self.0[a][b] += s * m.0[a][b];
            }
        }
    }
    /// Determinant and inverse by Gauss-Jordan elimination with partial pivoting;
    /// `None` when a pivot vanishes.
    pub fn determinant_and_inverse(&self) -> Option<(f64, Matrix<D>)> {
        let mut a = self.0;
        let mut inv = Self::scaled_identity(1.0).0;
        let mut det = 1.0;
        for col in 0..D {
            let mut piv = col;
            for r in col + 1..D {
                if a[r][col].abs() > a[piv][col].abs() {
                    piv = r;
                }
            }
            if a[piv][col] == 0.0 || !a[piv][col].is_finite() {
                return None;
            }
            if piv != col {
                a.swap(piv, col);
                inv.swap(piv, col);
                det = -det;
            }
            let d = a[col][col];
            det *= d;
            for b in 0..D {
                a[col][b] /= d;
                inv[col][b] /= d;
            }
            for r in 0..D {
                if r != col {
                    let f = a[r][col];
                    if f != 0.0 {
                        for b in 0..D {
                            a[r][b] -= f * a[col][b];
                            inv[r][b] -= f * inv[col][b];
                        }
                    }
                }
            }
        }
        Some((det, Matrix(inv)))
    }

    /// Inverse of a symmetric matrix with every eigenvalue raised to at least `floor` first:
    /// `V diag(1/max(lambda_k, floor)) V^T`. Equal to the inverse where no eigenvalue lies
    /// below `floor`; bounded by `1/floor` where the matrix is near-singular. `floor > 0`.
    pub fn floored_inverse(&self, floor: f64) -> Matrix<D> {
        let (lambda, v) = self.symmetric_eigen();
        let mut out = Self::zero();
        for (k, l) in lambda.iter().enumerate() {
            let s = 1.0 / l.max(floor);
            for a in 0..D {
                for b in 0..D {
                    out.0[a][b] += s * v.0[a][k] * v.0[b][k];
                }
            }
        }
        out
    }

    /// Eigenvalues and eigenvectors (the columns of the second result) of a symmetric
    /// matrix, by cyclic Jacobi rotations (Golub & Van Loan, Matrix Computations, s. 8.5).
    pub fn symmetric_eigen(&self) -> ([f64; D], Matrix<D>) {
        let mut a = self.0;
        let mut v = Self::scaled_identity(1.0).0;
        let scale: f64 = a.iter().flatten().map(|x| x * x).sum::<f64>().sqrt();
        for _sweep in 0..32 {
            let off: f64 = (0..D)
                .flat_map(|p| (p + 1..D).map(move |q| (p, q)))
                .map(|(p, q)| a[p][q] * a[p][q])
                .sum::<f64>()
                .sqrt();
            if off <= 1e-15 * scale || !off.is_finite() {
                break;
            }
            for p in 0..D {
                for q in p + 1..D {
                    if a[p][q] == 0.0 {
                        continue;
                    }
                    // The rotation (c, s) that zeroes a[p][q].
                    let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                    let c = 1.0 / (t * t + 1.0).sqrt();
                    let s = t * c;
                    for k in 0..D {
                        let (akp, akq) = (a[k][p], a[k][q]);
                        a[k][p] = c * akp - s * akq;
                        a[k][q] = s * akp + c * akq;
                    }
                    for k in 0..D {
                        let (apk, aqk) = (a[p][k], a[q][k]);
                        a[p][k] = c * apk - s * aqk;
                        a[q][k] = s * apk + c * aqk;
                    }
                    for row in v.iter_mut() {
                        let (vp, vq) = (row[p], row[q]);
                        row[p] = c * vp - s * vq;
                        row[q] = s * vp + c * vq;
                    }
                }
            }
        }
        let mut lambda = [0.0; D];
        for (k, l) in lambda.iter_mut().enumerate() {
            *l = a[k][k];
        }
        (lambda, Matrix(v))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_of_a_2x2_matrix() {
        let m = Matrix([[4.0, 1.0], [2.0, 3.0]]);
        let (det, inv) = m.determinant_and_inverse().unwrap();
        assert!((det - 10.0).abs() < 1e-12);
        let v = Vector([1.0, 2.0]);
        let back = m.mul_vec(&inv.mul_vec(&v));
        assert!((back - v).norm() < 1e-12);
    }

    #[test]
    fn singular_matrix_has_no_inverse() {
        assert!(Matrix([[1.0, 2.0], [2.0, 4.0]])
            .determinant_and_inverse()
            .is_none());
    }

    #[test]
    fn symmetric_eigen_reconstructs_a_3x3_matrix() {
        let m = Matrix([[2.0, 0.3, -0.5], [0.3, 1.0, 0.2], [-0.5, 0.2, 0.5]]);
        let (l, v) = m.symmetric_eigen();
        for a in 0..3 {
            for b in 0..3 {
                let back: f64 = (0..3).map(|k| v.0[a][k] * l[k] * v.0[b][k]).sum();
                assert!((back - m.0[a][b]).abs() < 1e-13, "{a}{b}: {back}");
                let dot: f64 = (0..3).map(|k| v.0[k][a] * v.0[k][b]).sum();
                assert!((dot - if a == b { 1.0 } else { 0.0 }).abs() < 1e-13);
            }
        }
        // Above the floor the floored inverse is the inverse.
        let inv = m.determinant_and_inverse().unwrap().1;
        let f = m.floored_inverse(1e-3);
        for a in 0..3 {
            for b in 0..3 {
                assert!((inv.0[a][b] - f.0[a][b]).abs() < 1e-11);
            }
        }
    }

    #[test]
    fn floored_inverse_of_a_singular_matrix_is_bounded() {
        // Rank one along (1, 1)/sqrt 2 with eigenvalue 0.4: inverted along it, 1/floor across.
        let m = Matrix([[0.2, 0.2], [0.2, 0.2]]);
        let f = m.floored_inverse(0.1);
        let along = f.mul_vec(&Vector([1.0, 1.0]));
        let across = f.mul_vec(&Vector([1.0, -1.0]));
        assert!((along - Vector([2.5, 2.5])).norm() < 1e-12, "{along:?}");
        assert!(
            (across - Vector([10.0, -10.0])).norm() < 1e-12,
            "{across:?}"
        );
    }
}
