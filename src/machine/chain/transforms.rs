//! Homogeneous transforms of the chain: translations, rotations and the
//! small-angle error matrix of `kinematics.md`.

use nalgebra::{Matrix3, Matrix4, Unit, Vector3};

use super::ErrorMotion;

/// The small-angle homogeneous error matrix of `kinematics.md`:
///
/// ```text
/// | 1    −εz   εy   δx |
/// | εz    1   −εx   δy |
/// | −εy   εx    1   δz |
/// | 0     0     0    1 |
/// ```
pub fn error_matrix(e: &ErrorMotion) -> Matrix4<f64> {
    Matrix4::new(
        1.0, -e[5], e[4], e[0], //
        e[5], 1.0, -e[3], e[1], //
        -e[4], e[3], 1.0, e[2], //
        0.0, 0.0, 0.0, 1.0,
    )
}

/// Derivative of [`error_matrix`] for a derivative of the error motions
/// (the identity drops out; the map is linear in `e`).
pub fn error_matrix_derivative(de: &ErrorMotion) -> Matrix4<f64> {
    Matrix4::new(
        0.0, -de[5], de[4], de[0], //
        de[5], 0.0, -de[3], de[1], //
        -de[4], de[3], 0.0, de[2], //
        0.0, 0.0, 0.0, 0.0,
    )
}

/// Homogeneous translation.
pub fn translation(v: &Vector3<f64>) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m[(0, 3)] = v.x;
    m[(1, 3)] = v.y;
    m[(2, 3)] = v.z;
    m
}

/// Rodrigues rotation `R = I + sinθ [u]x + (1 − cosθ)[u]x²` as a 3×3 matrix.
pub fn rotation3(u: &Unit<Vector3<f64>>, theta: f64) -> Matrix3<f64> {
    let k = u.cross_matrix();
    let (s, c) = theta.sin_cos();
    Matrix3::identity() + k * s + k * k * (1.0 - c)
}

/// `v` turned by `theta` (rad) about the unit axis `u` (Rodrigues on the
/// vector: `v cos θ + (u × v) sin θ + u (u·v)(1 − cos θ)`).
pub fn rotate(u: &Vector3<f64>, theta: f64, v: &Vector3<f64>) -> Vector3<f64> {
    let (s, c) = theta.sin_cos();
    v * c + u.cross(v) * s + u * (u.dot(v) * (1.0 - c))
}

/// Homogeneous rotation by `theta` (rad) about unit axis `u` through the origin.
pub fn rotation(u: &Unit<Vector3<f64>>, theta: f64) -> Matrix4<f64> {
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&rotation3(u, theta));
    m
}
