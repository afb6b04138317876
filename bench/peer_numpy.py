#!/usr/bin/env python3
"""Peer for the kinpost benchmark: seed 000's compensation method
(Zhao et al. 2022) vectorised in NumPy/SciPy, written the way a researcher
would write it.

Pipeline (file in, file out):
  1. read the pose program: G-code lines with X Y Z I J K words (modal), or a
     CSV of poses x,y,z,i,j,k;
  2. analytic inverse kinematics of the theoretical zhao2022-xzbc machine
     (chain from ../shared/spec/kinematics.md:
        revolute C axis [0,0,-1], prismatic X, prismatic Z,
        revolute B axis [0,1,0], translate [0,0,-20]);
  3. read the error tables (fixtures/errors/zhao2022-xzbc.csv), average the
     runs at each position and fit each column with a least-squares cubic
     B-spline (scipy make_lsq_spline, uniform interior knots), as in the
     paper's Section 6.1;
  4. Newton iteration of the paper (Eqs. 15-19): the stacked 6x4 theoretical
     Jacobian, its pseudo-inverse (np.linalg.pinv), the stacked residual of
     tool tip and tool axis on the actual machine; all poses at once, until
     max |dx| < tol or max iterations;
  5. write the axis program (X Z B C, mm and degrees, 4 decimals).

Prints (stderr) the iterations and the remaining tool-tip and axis errors of
the actual (error) model at the result.
"""

import argparse
import re
import sys
import time

import numpy as np
from scipy.interpolate import make_lsq_spline

TOOL = 20.0  # mm, tool tip from the B axis


# ---------------------------------------------------------------- input
WORD = re.compile(r"([XYZIJK])\s*([-+]?\d*\.?\d+)", re.IGNORECASE)


def read_poses(path):
    """Poses (N,6) and the index of the program line of each pose."""
    if path.endswith(".csv"):
        data = np.loadtxt(path, delimiter=",", comments="#")
        return data[:, :6], None
    lines = open(path).read().splitlines()
    modal = {"X": 0.0, "Y": 0.0, "Z": 0.0, "I": 0.0, "J": 0.0, "K": 1.0}
    poses, where = [], []
    for n, line in enumerate(lines):
        code = line.split("(")[0].split(";")[0]
        words = WORD.findall(code)
        if not words:
            continue
        for a, v in words:
            modal[a.upper()] = float(v)
        poses.append([modal[k] for k in "XYZIJK"])
        where.append(n)
    return np.array(poses), (lines, where)


# ---------------------------------------------------------------- kinematics
def rot_z(t):
    c, s = np.cos(t), np.sin(t)
    m = np.zeros(t.shape + (4, 4))
    m[..., 0, 0] = c
    m[..., 0, 1] = -s
    m[..., 1, 0] = s
    m[..., 1, 1] = c
    m[..., 2, 2] = 1
    m[..., 3, 3] = 1
    return m


def rot_y(t):
    c, s = np.cos(t), np.sin(t)
    m = np.zeros(t.shape + (4, 4))
    m[..., 0, 0] = c
    m[..., 0, 2] = s
    m[..., 2, 0] = -s
    m[..., 2, 2] = c
    m[..., 1, 1] = 1
    m[..., 3, 3] = 1
    return m


def trans(x, y, z):
    m = np.zeros(np.broadcast(x, y, z).shape + (4, 4))
    m[..., 0, 0] = m[..., 1, 1] = m[..., 2, 2] = m[..., 3, 3] = 1
    m[..., 0, 3] = x
    m[..., 1, 3] = y
    m[..., 2, 3] = z
    return m


def err_matrix(e):
    """Small-angle error matrix (N,4,4) from e (N,6) = dx dy dz ex ey ez."""
    m = np.zeros(e.shape[:-1] + (4, 4))
    m[..., 0, 0] = m[..., 1, 1] = m[..., 2, 2] = m[..., 3, 3] = 1
    m[..., 0, 1], m[..., 0, 2], m[..., 0, 3] = -e[..., 5], e[..., 4], e[..., 0]
    m[..., 1, 0], m[..., 1, 2], m[..., 1, 3] = e[..., 5], -e[..., 3], e[..., 1]
    m[..., 2, 0], m[..., 2, 1], m[..., 2, 3] = -e[..., 4], e[..., 3], e[..., 2]
    return m


def forward(q, errors=None):
    """Tool tip and axis (N,3) for joints q (N,4) = C X Z B (rad, mm)."""
    C, X, Z, B = q.T
    zero = np.zeros_like(X)
    T = rot_z(-C)  # revolute C about [0,0,-1]
    mX = trans(X, zero, zero)
    mZ = trans(zero, zero, Z)
    mB = rot_y(B)
    if errors is not None:
        mX = mX @ err_matrix(errors["X"](X))
        mZ = mZ @ err_matrix(errors["Z"](Z))
        mB = mB @ err_matrix(errors["B"](np.degrees(B)))
    T = T @ mX @ mZ @ mB @ trans(zero, zero, zero - TOOL)
    return T[:, :3, 3], T[:, :3, 2]


def ik(poses):
    """Analytic IK of the theoretical machine: C from the tip azimuth, B
    from the tool axis turned back by C, then X and Z."""
    p, o = poses[:, :3], poses[:, 3:6]
    o = o / np.linalg.norm(o, axis=1, keepdims=True)
    C = np.unwrap(np.arctan2(-p[:, 1], p[:, 0]))
    cc, sc = np.cos(C), np.sin(C)
    ox = cc * o[:, 0] - sc * o[:, 1]
    B = np.arctan2(ox, o[:, 2])
    a = cc * p[:, 0] - sc * p[:, 1]
    X = a + TOOL * np.sin(B)
    Z = p[:, 2] + TOOL * np.cos(B)
    return np.stack([C, X, Z, B], axis=1), o


def jacobian_theoretical(q):
    """Analytic 6x4 Jacobian of [tip; axis] of the error-free chain (N,6,4)."""
    C, X, Z, B = q.T
    cc, sc, cb, sb = np.cos(C), np.sin(C), np.cos(B), np.sin(B)
    a = X - TOOL * sb
    J = np.zeros((len(C), 6, 4))
    # tip = (cC a, -sC a, Z - 20 cB); axis = (cC sB, -sC sB, cB)
    J[:, 0, 0], J[:, 1, 0] = -sc * a, -cc * a
    J[:, 0, 1], J[:, 1, 1] = cc, -sc
    J[:, 2, 2] = 1
    J[:, 0, 3], J[:, 1, 3], J[:, 2, 3] = -cc * TOOL * cb, sc * TOOL * cb, TOOL * sb
    J[:, 3, 0], J[:, 4, 0] = -sc * sb, -cc * sb
    J[:, 3, 3], J[:, 4, 3], J[:, 5, 3] = cc * cb, -sc * cb, -sb
    return J


# ---------------------------------------------------------------- errors
COMPONENT = {"X": 0, "Y": 1, "Z": 2, "A": 3, "B": 4, "C": 5}


def read_error_tables(path, interior_knots=4):
    """Per axis a function pos -> (N,6) error motions, from the CSV blocks
    (header `AXIS,E<comp><axis>,...`), least-squares cubic B-splines."""
    blocks, cur = {}, None
    for line in open(path):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        cells = line.split(",")
        if cells[0].isalpha():
            cur = (cells[0], cells[1:])
            blocks[cur[0]] = (cur[1], [])
        else:
            blocks[cur[0]][1].append([float(c) for c in cells])
    fits = {}
    for axis, (names, rows) in blocks.items():
        data = np.array(rows)
        pos = np.unique(data[:, 0])
        mean = np.array([data[data[:, 0] == p, 1:].mean(axis=0) for p in pos])
        k = 3
        inner = np.linspace(pos[0], pos[-1], interior_knots + 2)[1:-1]
        t = np.r_[[pos[0]] * (k + 1), inner, [pos[-1]] * (k + 1)]
        splines = [
            (COMPONENT[name[1]], make_lsq_spline(pos, mean[:, c], t, k=k))
            for c, name in enumerate(names)
        ]

        def f(x, splines=splines, lo=pos[0], hi=pos[-1]):
            x = np.clip(x, lo, hi)
            e = np.zeros(x.shape + (6,))
            for comp, s in splines:
                e[..., comp] = s(x)
            return e

        fits[axis] = f
    for axis in "XZB":
        fits.setdefault(axis, lambda x: np.zeros(np.shape(x) + (6,)))
    return fits


# ---------------------------------------------------------------- Newton
def compensate(poses, errors, tol=1e-6, max_iter=20):
    q0, axis = ik(poses)
    q = q0.copy()
    target_p, target_o = poses[:, :3], axis
    for it in range(1, max_iter + 1):
        p, o = forward(q, errors)
        r = np.concatenate([target_p - p, target_o - o], axis=1)  # (N,6)
        J = jacobian_theoretical(q)
        dx = np.einsum("nij,nj->ni", np.linalg.pinv(J), r)
        q += dx
        if np.max(np.linalg.norm(dx, axis=1)) < tol:
            break
    p, o = forward(q, errors)
    tip = np.linalg.norm(p - target_p, axis=1)
    ang = np.arctan2(np.linalg.norm(np.cross(o, target_o), axis=1), np.sum(o * target_o, axis=1))
    return q, it, tip, ang


# ---------------------------------------------------------------- output
def write_program(path, q, src):
    C, X, Z, B = q.T
    out = [
        f"X{x:.4f} Z{z:.4f} B{b:.4f} C{c:.4f}"
        for x, z, b, c in zip(X, Z, np.degrees(B), np.degrees(C))
    ]
    if src is not None:
        lines, where = src
        lines = list(lines)
        for k, n in enumerate(where):
            lines[n] = ("G1 " if lines[n].upper().startswith("G1") else "") + out[k]
        out = lines
    with open(path, "w") as f:
        f.write("\n".join(out) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("program", help="pose program (.nc G-code or .csv x,y,z,i,j,k)")
    ap.add_argument("--errors", required=True, help="error table CSV")
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--tol", type=float, default=1e-6, help="stop when max |dx| < tol")
    ap.add_argument("--max-iter", type=int, default=20)
    a = ap.parse_args()
    t0 = time.perf_counter()
    poses, src = read_poses(a.program)
    errors = read_error_tables(a.errors)
    q, it, tip, ang = compensate(poses, errors, a.tol, a.max_iter)
    write_program(a.output, q, src)
    print(
        f"peer: {len(poses)} poses, {it} iterations, tool-tip residual max {tip.max():.3e} mm "
        f"(mean {tip.mean():.3e}), axis residual max {ang.max() * 1e6:.4f} urad, "
        f"{time.perf_counter() - t0:.2f} s",
        file=sys.stderr,
    )


if __name__ == "__main__":
    main()
