//! The general evaluator with full 4×4 matrices, element by element: the
//! reference the precomputed evaluator (`compiled.rs`) is checked against
//! in the tests. Test-only: every chain is evaluated by the precomputed form.

use nalgebra::{Matrix4, Vector3, Vector4};

use super::*;

impl Chain {
    /// Derivative `dM_j/dq` of the joint motion.
    fn joint_motion_derivative(&self, j: usize, q: f64) -> Matrix4<f64> {
        let joint = &self.joints[j];
        match joint.kind {
            JointKind::Prismatic => {
                let mut m = Matrix4::zeros();
                let u = joint.axis.into_inner();
                m[(0, 3)] = u.x;
                m[(1, 3)] = u.y;
                m[(2, 3)] = u.z;
                m
            }
            JointKind::Revolute => {
                let mut m = Matrix4::zeros();
                let r = joint.axis.cross_matrix() * rotation3(&joint.axis, q);
                m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
                m
            }
        }
    }

    /// Transform of joint `j` including its error motion: `M_j(q) · E_j(q)`.
    fn joint_transform(&self, j: usize, q: f64, errors: &dyn JointErrors) -> Matrix4<f64> {
        let m = self.joint_motion(j, q);
        match errors.error(j, q) {
            Some(e) => m * error_matrix(&e),
            None => m,
        }
    }

    /// [`Chain::transform`] with full 4×4 matrices, element by element.
    fn transform_general(&self, q: &[f64], errors: &dyn JointErrors) -> Matrix4<f64> {
        let mut t = Matrix4::identity();
        for el in &self.elements {
            match el {
                Element::Fixed(m) => t *= m,
                Element::Joint(j) => t *= self.joint_transform(*j, q[*j], errors),
            }
        }
        t
    }

    /// [`Chain::pose_and_jacobian`] with full 4×4 matrices, element by element
    /// (chains with a fixed element that is not affine).
    fn pose_and_jacobian_general(&self, q: &[f64], errors: &dyn JointErrors) -> (Pose, Jacobian) {
        let n = self.joints.len();
        debug_assert_eq!(q.len(), n);
        // Per-joint transforms and derivatives.
        let mut g = [Matrix4::<f64>::identity(); MAX_JOINTS];
        let mut dg = [Matrix4::<f64>::zeros(); MAX_JOINTS];
        for j in 0..n {
            let m = self.joint_motion(j, q[j]);
            let dm = self.joint_motion_derivative(j, q[j]);
            match errors.error_and_derivative(j, q[j]) {
                Some((e, de)) => {
                    let em = error_matrix(&e);
                    g[j] = m * em;
                    dg[j] = dm * em + m * error_matrix_derivative(&de);
                }
                None => {
                    g[j] = m;
                    dg[j] = dm;
                }
            }
        }
        let elem = |el: &Element| -> Matrix4<f64> {
            match el {
                Element::Fixed(m) => *m,
                Element::Joint(j) => g[*j],
            }
        };
        // Backward pass: suffix applied to tip point and axis direction.
        let ne = self.elements.len();
        let mut s_tip = Vector4::new(0.0, 0.0, 0.0, 1.0);
        let mut s_ax = Vector4::new(0.0, 0.0, 1.0, 0.0);
        let mut suffix = [(Vector4::zeros(), Vector4::zeros()); MAX_JOINTS];
        for i in (0..ne).rev() {
            if let Element::Joint(j) = self.elements[i] {
                suffix[j] = (s_tip, s_ax);
            }
            let m = elem(&self.elements[i]);
            s_tip = m * s_tip;
            s_ax = m * s_ax;
        }
        // Forward pass: prefix products.
        let mut jac = Jacobian::zeros(n);
        let mut prefix = Matrix4::<f64>::identity();
        for el in &self.elements {
            if let Element::Joint(j) = el {
                let d = prefix * dg[*j];
                let (st, sa) = suffix[*j];
                let dt = d * st;
                let da = d * sa;
                jac[(0, *j)] = dt[0];
                jac[(1, *j)] = dt[1];
                jac[(2, *j)] = dt[2];
                jac[(3, *j)] = da[0];
                jac[(4, *j)] = da[1];
                jac[(5, *j)] = da[2];
            }
            prefix *= elem(el);
        }
        let pose = Pose {
            tip: Vector3::new(prefix[(0, 3)], prefix[(1, 3)], prefix[(2, 3)]),
            axis: Vector3::new(prefix[(0, 2)], prefix[(1, 2)], prefix[(2, 2)]),
        };
        (pose, jac)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Smooth error motions on every joint, large enough to matter.
    struct Wavy;
    impl JointErrors for Wavy {
        fn error(&self, joint: usize, q: f64) -> Option<ErrorMotion> {
            let s = (joint as f64 + 1.0) * 2e-3;
            Some(ErrorMotion::new(
                s * (0.1 * q).sin(),
                s * (0.07 * q).cos(),
                s * q * 0.01,
                s * 1e-2 * (0.05 * q).sin(),
                s * 1e-2 * q,
                s * 1e-2 * (0.3 * q).cos(),
            ))
        }
    }

    /// The precomputed evaluator (the one every caller uses) agrees with
    /// the element-by-element 4×4 products on both seed machines, with and
    /// without error motions and with fixed error elements inserted: the
    /// transform, the pose, the Jacobian, the pose near known sines, and
    /// the prismatic directions.
    #[test]
    fn the_one_evaluator_matches_the_general_reference() {
        let e = ErrorMotion::new(0.01, -0.02, 0.005, 1e-4, -2e-4, 3e-4);
        let mut chains = Vec::new();
        for name in [
            "zhao2022-xzbc",
            "wang2023-xyzab",
            "xyzac-trt",
            "xyzbc-nutating",
        ] {
            let c = crate::machine::Machine::embedded(name).unwrap().chain;
            let with_fixed = c
                .with_fixed_inserted(0, error_matrix(&e))
                .with_fixed_inserted(
                    c.elements().len(),
                    translation(&Vector3::new(1.0, 2.0, 3.0)),
                );
            chains.push(c);
            chains.push(with_fixed);
        }
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut checked = 0;
        for c in &chains {
            for _ in 0..20 {
                let q: Vec<f64> = (0..c.dof()).map(|_| -2.0 + 4.0 * uniform()).collect();
                for errors in [&NoErrors as &dyn JointErrors, &Wavy] {
                    let t = c.transform(&q, errors);
                    let t_ref = c.transform_general(&q, errors);
                    assert!((t - t_ref).amax() < 1e-12, "{t} vs {t_ref}");
                    let p = c.pose(&q, errors);
                    let (p_ref, jac_ref) = c.pose_and_jacobian_general(&q, errors);
                    assert!((p.tip - p_ref.tip).amax() < 1e-12);
                    assert!((p.axis - p_ref.axis).amax() < 1e-15);
                    let (p2, jac) = c.pose_and_jacobian(&q, errors);
                    assert!((p2.tip - p_ref.tip).amax() < 1e-12);
                    assert!((&jac - &jac_ref).amax() < 1e-12, "{jac} vs {jac_ref}");
                    let near = c.trig_at(&q);
                    let mut qn = q.clone();
                    for v in &mut qn {
                        *v += 2e-6;
                    }
                    let pn = c.pose_near(&qn, errors, &near);
                    let (pn_ref, _) = c.pose_and_jacobian_general(&qn, errors);
                    assert!((pn.tip - pn_ref.tip).amax() < 1e-12);
                    checked += 1;
                }
                let mut dirs = [[f64::NAN; 3]; MAX_JOINTS];
                let p = c.pose_and_prismatic_directions(&q, &mut dirs);
                let (p_ref, jac_ref) = c.pose_and_jacobian_general(&q, &NoErrors);
                assert!((p.tip - p_ref.tip).amax() < 1e-12);
                for (j, joint) in c.joints().iter().enumerate() {
                    if joint.kind == JointKind::Prismatic {
                        for r in 0..3 {
                            assert!((dirs[j][r] - jac_ref[(r, j)]).abs() < 1e-14);
                        }
                    }
                }
            }
        }
        assert_eq!(checked, chains.len() * 20 * 2);
    }
}
