//! What the unit tests of several layers share (compiled for tests only):
//! a deterministic generator of test numbers, and pseudo-inverses
//! evaluated independently of the code under test.

use nalgebra::DMatrix;

/// A 64-bit linear congruential generator (Knuth's MMIX constants):
/// deterministic test numbers, the same on every platform. Not for
/// simulated measurements (`diagnose::rng` is).
#[derive(Debug, Clone)]
pub struct Lcg(pub u64);

impl Lcg {
    /// The next state, which is also the next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0
    }

    /// Uniform in `[0, 1)` (the top 53 bits of the next state).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[-1, 1)`.
    pub fn signed(&mut self) -> f64 {
        self.unit() * 2.0 - 1.0
    }
}

/// `B⁺ = (Bᵀ B)⁻¹ Bᵀ` of a matrix of full column rank (LU of the Gram
/// matrix): an independent reference for pseudo-inverses of products
/// `A = B C`, whose `A⁺ = C⁺ B⁺`.
pub fn left_inverse(b: &DMatrix<f64>) -> DMatrix<f64> {
    (b.transpose() * b)
        .lu()
        .solve(&b.transpose())
        .expect("full column rank")
}

/// `C⁺ = Cᵀ (C Cᵀ)⁻¹` of a matrix of full row rank (see [`left_inverse`]).
pub fn right_inverse(c: &DMatrix<f64>) -> DMatrix<f64> {
    (c * c.transpose())
        .lu()
        .solve(c)
        .expect("full row rank")
        .transpose()
}
