//! The rotary joints from the tool axis, by family: one revolute
//! (subproblem 1), two revolutes (subproblem 2, two branches) and the RTTR
//! four-axis machines (the first rotary from the tip azimuth, the second
//! from the projected tool axis).

use super::*;

impl IkSolver {
    /// Checks the RTTR structure (see the module docs) and returns its frame.
    pub(super) fn rttr_frame(&self, cols: &[Vector3<f64>]) -> Option<RttrFrame> {
        let first = self.chain.joints()[0].element;
        let mut pre = Matrix4::identity();
        for el in &self.chain.elements()[..first] {
            if let Element::Fixed(m) = el {
                pre *= m;
            }
        }
        let pre_inv = pre.try_inverse()?;
        let pre_rot_t = rot3(&pre).transpose();
        // Everything below in the frame just after the first revolute (at 0).
        let d1 = pre_rot_t * cols[0];
        let d2 = pre_rot_t * cols[1];
        let n = d1.cross(&d2).try_normalize(STRUCT_TOL)?;
        let u1 = self.u(self.revolutes[0]);
        if u1.dot(&n).abs() > STRUCT_TOL {
            return None;
        }
        let k2 = self.segs[1] * self.u(self.revolutes[1]);
        if k2.cross(&n).norm() > STRUCT_TOL {
            return None;
        }
        let pose0 = self.chain.pose(&vec![0.0; self.chain.dof()], &NoErrors);
        let axis_f = pre_rot_t * pose0.axis;
        if axis_f.dot(&n).abs() > STRUCT_TOL {
            return None;
        }
        let tip_f = (pre_inv * pose0.tip.push(1.0)).xyz();
        if tip_f.dot(&n).abs() > STRUCT_TOL * (1.0 + tip_f.norm()) {
            return None;
        }
        let d = n.cross(&u1).normalize();
        Some(RttrFrame { pre_inv, n, d })
    }

    pub(super) fn orient_1r(&self, target: &Pose, reference: &[f64]) -> RawBranches {
        let j1 = self.revolutes[0];
        let k = self.u(j1);
        let p = self.segs[1] * Vector3::z();
        let qt = self.segs[0].transpose() * target.axis;
        let mut q = [0.0; crate::machine::chain::MAX_JOINTS];
        let (t, singular) = match subproblem1(&k, &p, &qt, self.options.singular_tol_rad) {
            Some(t) => (t, false),
            None => (reference[j1], true),
        };
        q[j1] = t;
        [Raw {
            q,
            singular,
            branch: 0,
        }]
        .into_iter()
        .collect()
    }

    pub(super) fn orient_2r(&self, target: &Pose, reference: &[f64]) -> RawBranches {
        let (j1, j2) = (self.revolutes[0], self.revolutes[1]);
        let k1 = self.u(j1);
        let k2 = self.segs[1] * self.u(j2);
        let p = self.segs[1] * self.segs[2] * Vector3::z();
        let qt = self.segs[0].transpose() * target.axis;
        if k1.cross(&qt).norm() <= self.options.singular_tol_rad {
            // Tool axis along the first rotary: it is free; keep it and turn
            // the second rotary onto the axis.
            let t1 = reference[j1];
            let back = rotate(&k1, -t1, &qt);
            let t2 = subproblem1(&k2, &p, &back, 0.0).unwrap_or_else(|| reference[j2]);
            let mut q = [0.0; crate::machine::chain::MAX_JOINTS];
            q[j1] = t1;
            q[j2] = t2;
            return [Raw {
                q,
                singular: true,
                branch: 0,
            }]
            .into_iter()
            .collect();
        }
        subproblem2(&k1, &k2, &p, &qt)
            .into_iter()
            .enumerate()
            .map(|(b, (t1, t2))| {
                let mut q = [0.0; crate::machine::chain::MAX_JOINTS];
                q[j1] = t1;
                q[j2] = t2;
                Raw {
                    q,
                    singular: false,
                    branch: b as u8,
                }
            })
            .collect()
    }

    /// The first rotary's angles of an RTTR machine for `target`: two
    /// branches half a turn apart, or one when it is free (singular).
    pub(super) fn rttr_angles(&self, target: &Pose, reference: &[f64]) -> Option<RttrAngles> {
        let f = self.rttr.as_ref()?;
        let j1 = self.revolutes[0];
        // Tip and axis in the frame just before the first revolute.
        let p = (f.pre_inv * target.tip.push(1.0)).xyz();
        let o = self.segs[0].transpose() * target.axis;
        // The first rotary must bring both into the plane ⟂ n: the tip
        // azimuth (weighted strongly) and the axis azimuth, combined in
        // doubled angles because each is only defined modulo π.
        let (pa, pb) = (p.dot(&f.d), p.dot(&f.n));
        let (oa, ob) = (o.dot(&f.d), o.dot(&f.n));
        let w2 = self.options.rttr_axis_weight_mm.powi(2);
        let zr = pa * pa - pb * pb + w2 * (oa * oa - ob * ob);
        let zi = 2.0 * pa * pb + w2 * 2.0 * oa * ob;
        // The tip on the first rotary's axis and the tool axis along it,
        // compared squared (no `hypot`: the IK has already refused
        // coordinates anywhere near overflow).
        let within = |a: f64, b: f64, tol: f64| tol >= 0.0 && a * a + b * b <= tol * tol;
        Some(
            if (within(pa, pb, self.options.on_axis_tol_mm)
                && within(oa, ob, self.options.singular_tol_rad))
                || (zr == 0.0 && zi == 0.0)
            {
                RttrAngles {
                    t1: [reference[j1], 0.0],
                    count: 1,
                    singular: true,
                    o,
                }
            } else {
                let t = 0.5 * zi.atan2(zr);
                RttrAngles {
                    t1: [t, t + PI],
                    count: 2,
                    singular: false,
                    o,
                }
            },
        )
    }

    /// A lower bound of the distance from `reference` of branch `b` of
    /// [`IkSolver::rttr_angles`], from its first rotary alone (the second
    /// costs a subproblem): the distance of the branch with only its first
    /// rotary moved, the other terms zero.
    pub(super) fn rttr_lower(&self, a: &RttrAngles, b: usize, reference: &[f64]) -> f64 {
        let j1 = self.revolutes[0];
        let t = choose_turn(&self.axes[j1], a.t1[b], reference[j1]);
        self.distance_term(j1, t, reference[j1], 0.0)
    }

    /// Branch `b` of [`IkSolver::rttr_angles`]: the second rotary turns the
    /// tool axis into place.
    pub(super) fn rttr_branch(&self, a: &RttrAngles, b: usize, reference: &[f64]) -> Raw {
        let (j1, j2) = (self.revolutes[0], self.revolutes[1]);
        let (u1, u2) = (self.u(j1), self.u(j2));
        let t1 = a.t1[b];
        // Tool axis in the frame before the second revolute.
        let back = self.segs[1].transpose() * rotate(&u1, -t1, &a.o);
        let pz = self.segs[2] * Vector3::z();
        let (t2, s2) = match subproblem1(&u2, &pz, &back, self.options.singular_tol_rad) {
            Some(t2) => (t2, false),
            None => (reference[j2], true),
        };
        let mut q = [0.0; crate::machine::chain::MAX_JOINTS];
        q[j1] = t1;
        q[j2] = t2;
        Raw {
            q,
            singular: a.singular || s2,
            branch: b as u8,
        }
    }
}

/// The first rotary's angles of an RTTR machine ([`IkSolver::rttr_angles`]).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct RttrAngles {
    /// The angle of each branch, rad.
    pub(super) t1: [f64; 2],
    /// Branches: 2, or 1 when the first rotary is free.
    pub(super) count: usize,
    pub(super) singular: bool,
    /// The tool axis in the frame before the first revolute.
    pub(super) o: Vector3<f64>,
}
