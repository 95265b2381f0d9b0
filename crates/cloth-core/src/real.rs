//! Floating-point precision used by the CPU reference, and a minimal 3-vector.
//!
//! The reference stepper is generic over [`Real`] so that the same code runs in
//! `f32` (to compare bit-for-bit-ish with the GPU) and in `f64` (a high-precision
//! oracle). [`Vec3`] is deliberately tiny: only the operations the force model uses.
//!
//! Every operation is `#[inline]`: each is a few instructions, and a lightly optimised build
//! (the test profile) otherwise keeps one of the two precisions' copies as calls, which made the
//! f64 reference several times slower than the f32 one.

use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A floating-point type the reference can run in: `f32` or `f64`.
pub trait Real:
    num_traits::Float + num_traits::FromPrimitive + Send + Sync + std::fmt::Debug + Default + 'static
{
    /// Converts from `f64` (scene values are stored in `f64`).
    #[inline]
    fn of(value: f64) -> Self {
        Self::from_f64(value).unwrap_or_else(Self::nan)
    }
    /// Converts to `f64` for reporting.
    #[inline]
    fn to_f64_lossy(self) -> f64 {
        num_traits::ToPrimitive::to_f64(&self).unwrap_or(f64::NAN)
    }
}
impl Real for f32 {}
impl Real for f64 {}

/// A 3-vector of [`Real`] components (positions in m, velocities in m/s, forces in N).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3<R> {
    /// x component.
    pub x: R,
    /// y component.
    pub y: R,
    /// z component.
    pub z: R,
}

impl<R: Real> Vec3<R> {
    /// The zero vector.
    #[inline]
    pub fn zero() -> Self {
        Self::new(R::zero(), R::zero(), R::zero())
    }
    /// Builds a vector from its components.
    #[inline]
    pub fn new(x: R, y: R, z: R) -> Self {
        Self { x, y, z }
    }
    /// Converts an `[f64; 3]` (scene units) to this precision.
    #[inline]
    pub fn from_f64(v: [f64; 3]) -> Self {
        Self::new(R::of(v[0]), R::of(v[1]), R::of(v[2]))
    }
    /// Converts an `[f32; 3]` (GPU layout) to this precision.
    #[inline]
    pub fn from_f32(v: [f32; 3]) -> Self {
        Self::from_f64([v[0] as f64, v[1] as f64, v[2] as f64])
    }
    /// Components as `f64`.
    #[inline]
    pub fn to_f64(self) -> [f64; 3] {
        [self.x.to_f64_lossy(), self.y.to_f64_lossy(), self.z.to_f64_lossy()]
    }
    /// Cross product `a × b`.
    #[inline]
    pub fn cross(self, o: Self) -> Self {
        Self::new(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)
    }
    /// Dot product `a · b`.
    #[inline]
    pub fn dot(self, other: Self) -> R {
        self.x * other.x + self.y * other.y + self.z * other.z
    }
    /// Euclidean length `|a|`.
    #[inline]
    pub fn length(self) -> R {
        self.dot(self).sqrt()
    }
    /// `true` when every component is finite.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
}

impl<R: Real> Add for Vec3<R> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl<R: Real> Sub for Vec3<R> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl<R: Real> Neg for Vec3<R> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self::new(-self.x, -self.y, -self.z)
    }
}
impl<R: Real> Mul<R> for Vec3<R> {
    type Output = Self;
    #[inline]
    fn mul(self, s: R) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
}
impl<R: Real> AddAssign for Vec3<R> {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<R: Real> SubAssign for Vec3<R> {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}

/// A 3 × 3 matrix of [`Real`] components, by rows: the blocks of the force Jacobians that implicit
/// integrators solve with (stiffness in N/m, damping in N·s/m).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Mat3<R> {
    /// The rows.
    pub rows: [Vec3<R>; 3],
}

impl<R: Real> Mat3<R> {
    /// The zero matrix.
    #[inline]
    pub fn zero() -> Self {
        Self { rows: [Vec3::zero(); 3] }
    }

    /// The identity.
    #[inline]
    pub fn identity() -> Self {
        let (o, l) = (R::zero(), R::one());
        Self { rows: [Vec3::new(l, o, o), Vec3::new(o, l, o), Vec3::new(o, o, l)] }
    }

    /// The outer product `a bᵀ`.
    #[inline]
    pub fn outer(a: Vec3<R>, b: Vec3<R>) -> Self {
        Self { rows: [b * a.x, b * a.y, b * a.z] }
    }

    /// `M v`.
    #[inline]
    pub fn mul_vec(&self, v: Vec3<R>) -> Vec3<R> {
        Vec3::new(self.rows[0].dot(v), self.rows[1].dot(v), self.rows[2].dot(v))
    }

    /// The determinant.
    #[inline]
    pub fn determinant(&self) -> R {
        let [a, b, c] = self.rows;
        a.dot(b.cross(c))
    }

    /// The inverse, `None` where the determinant is zero or not finite.
    #[inline]
    pub fn inverse(&self) -> Option<Self> {
        let [a, b, c] = self.rows;
        let det = self.determinant();
        if det == R::zero() || !det.is_finite() {
            return None;
        }
        // The columns of the inverse are the cross products of the rows, over the determinant.
        let columns = [b.cross(c), c.cross(a), a.cross(b)];
        let inv = R::one() / det;
        let row = |k: usize| {
            let pick = |v: Vec3<R>| [v.x, v.y, v.z][k];
            Vec3::new(pick(columns[0]), pick(columns[1]), pick(columns[2])) * inv
        };
        Some(Self { rows: [row(0), row(1), row(2)] })
    }
}

impl<R: Real> Add for Mat3<R> {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self { rows: [self.rows[0] + o.rows[0], self.rows[1] + o.rows[1], self.rows[2] + o.rows[2]] }
    }
}

impl<R: Real> Sub for Mat3<R> {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        Self { rows: [self.rows[0] - o.rows[0], self.rows[1] - o.rows[1], self.rows[2] - o.rows[2]] }
    }
}

impl<R: Real> Mul<R> for Mat3<R> {
    type Output = Self;
    #[inline]
    fn mul(self, s: R) -> Self {
        Self { rows: [self.rows[0] * s, self.rows[1] * s, self.rows[2] * s] }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_matrix_times_its_inverse_is_the_identity() {
        let m = Mat3 { rows: [Vec3::new(4.0, 1.0, 0.5), Vec3::new(1.0, 3.0, -1.0), Vec3::new(0.5, -1.0, 2.0)] };
        let inv = m.inverse().expect("invertible");
        for k in 0..3 {
            let e = Mat3::<f64>::identity().rows[k];
            let back = m.mul_vec(inv.mul_vec(e)) - e;
            assert!(back.length() < 1e-14, "column {k}: {back:?}");
        }
        let singular = Mat3::outer(Vec3::new(1.0, 2.0, 3.0), Vec3::new(0.0, 1.0, 1.0));
        assert_eq!(singular.inverse(), None, "a rank-one matrix has no inverse");
    }

    #[test]
    fn the_outer_product_maps_b_onto_a() {
        let (a, b) = (Vec3::new(1.0, -2.0, 0.5), Vec3::new(3.0, 0.0, 4.0));
        let m = Mat3::outer(a, b);
        // (a bᵀ) b = a |b|².
        assert!((m.mul_vec(b) - a * 25.0).length() < 1e-12);
        assert!((m.mul_vec(Vec3::new(4.0, 0.0, -3.0))).length() < 1e-12, "b's orthogonal complement maps to 0");
    }
}
