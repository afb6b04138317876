# kinpost_post.py — a FreeCAD Path (CAM) post-processor that hands the tool
# poses to kinpost.
#
# FreeCAD's Path workbench computes tool paths in the job's frame (the part's
# frame).  This post writes them as tool poses — tool tip X Y Z and unit tool
# vector I J K on every straight move — and pipes that program through
#
#     kinpost post --machine <machine> -o <file> -
#
# which turns every pose into the axis words of one particular machine
# (inverse kinematics, limits, rotary unwinding; see docs/programs.md).
# Where FreeCAD hands over a file name (FreeCAD 0.x), kinpost writes that
# file atomically: if kinpost rejects a block, the error (file:line:col, the
# offending text) is raised in FreeCAD and the file is left as it was.
# FreeCAD 1.x calls export(objects, "-", args) and writes the returned text
# itself: then the program comes back from kinpost's standard output, and
# an error raises before FreeCAD has anything to write.
#
# Nothing in the job is dropped: moves become tool poses (the first moves,
# which give only some of X Y Z, take the others from the next move that
# gives them, with a comment saying so), tool changes, spindle, coolant and
# dwell commands keep their words (M6 T2, M3 S12000, G4 P1), comments stay
# comments, and a command this post does not convert (a canned cycle, G91,
# G28, G92, an unknown command) raises an error naming it.
#
# Install: copy this file into FreeCAD's macro directory (or any directory
# listed under Preferences → Path/CAM → Job → "Custom post processor
# location"), keeping the name ending in `_post.py`; choose "kinpost" as the
# job's post processor.  Arguments (the job's "Post Processor Arguments"):
#
#     --machine FILE|NAME   machine file or embedded machine name (required
#                           unless KINPOST_MACHINE is set)
#     --kinpost PATH        the kinpost binary (default: `kinpost` on PATH,
#                           or KINPOST)
#     --decimals N          decimals of the axis words (default: the machine's)
#     --arc-tolerance MM    chord error when linearising G2/G3, mm (0.001)
#     --tool-axis I,J,K     tool axis of moves that carry none (default 0,0,1:
#                           FreeCAD's 3-axis operations cut along +Z)
#     --poses-only          write the pose program and do not run kinpost
#     --tool-length MM, --work-offset X,Y,Z, --tool-table FILE, --feed MODE
#                           passed to kinpost post (docs/cli.md: the job
#                           set-up, feeds)
#
# Tool axes: a straight move whose parameters carry I, J and K (as 4/5-axis
# add-ons write them) uses that vector; any other move keeps the current
# tool axis.  Arcs (G2/G3, XY plane) are linearised here: kinpost accepts
# only straight moves in pose mode.
#
# Tested outside FreeCAD by `python3 kinpost_post.py --self-test` (builds a
# small fake job and checks the pose program), which needs no FreeCAD.

import math
import os
import shlex
import subprocess
import sys

TOOLTIP = """Tool poses (X Y Z + I J K) converted to machine axes by kinpost."""

TOOLTIP_ARGS = """
--machine FILE|NAME   machine file or embedded kinpost machine (required)
--kinpost PATH        kinpost binary (default: kinpost)
--decimals N          decimals of the axis words
--arc-tolerance MM    chord error of linearised arcs, mm (default 0.001)
--tool-axis I,J,K     tool axis of moves without one (default 0,0,1)
--poses-only          write the pose program, do not run kinpost
--tool-length MM, --work-offset X,Y,Z, --tool-table FILE, --feed MODE
                      passed to kinpost post
"""

# Options handed to `kinpost post` as they are.
KINPOST_OPTIONS = ("--tool-length", "--work-offset", "--tool-table", "--feed")

MOTION = {"G0", "G00", "G1", "G01"}
ARCS = {"G2", "G02", "G3", "G03"}
# Commands written as they are, with their words (T of M6, S of M3, P of G4…).
PASS_THROUGH = {"G17", "G18", "G19", "G20", "G21", "G40", "G49", "G54",
                "G55", "G56", "G57", "G58", "G59", "G80", "G90", "G93", "G94",
                "G4", "G04", "M0", "M00", "M1", "M01", "M2", "M02", "M3", "M03",
                "M4", "M04", "M5", "M05", "M6", "M06", "M7", "M07", "M8", "M08",
                "M9", "M09", "M30"}
# Commands that would move the tool in a way this wrapper does not convert:
# refused with a message, never dropped.
REFUSED = {
    "G73": "a canned cycle", "G76": "a canned cycle", "G81": "a canned cycle",
    "G82": "a canned cycle", "G83": "a canned cycle", "G84": "a canned cycle",
    "G85": "a canned cycle", "G86": "a canned cycle", "G87": "a canned cycle",
    "G88": "a canned cycle", "G89": "a canned cycle",
    "G91": "incremental distance mode (FreeCAD paths are absolute)",
    "G28": "a move to a reference point", "G30": "a move to a reference point",
    "G92": "a coordinate offset", "G53": "a move in machine coordinates",
}


def parse_args(argstring):
    opts = {
        "machine": os.environ.get("KINPOST_MACHINE"),
        "kinpost": os.environ.get("KINPOST", "kinpost"),
        "decimals": None,
        "arc_tolerance": 0.001,
        "tool_axis": (0.0, 0.0, 1.0),
        "poses_only": False,
        "kinpost_args": [],
    }
    args = shlex.split(argstring or "")
    i = 0
    while i < len(args):
        a = args[i]
        value = args[i + 1] if i + 1 < len(args) else None
        if a == "--poses-only":
            opts["poses_only"] = True
            i += 1
            continue
        if value is None:
            raise ValueError("kinpost_post: %s needs a value" % a)
        if a in KINPOST_OPTIONS:
            opts["kinpost_args"] += [a, value]
        elif a == "--machine":
            opts["machine"] = value
        elif a == "--kinpost":
            opts["kinpost"] = value
        elif a == "--decimals":
            opts["decimals"] = int(value)
        elif a == "--arc-tolerance":
            opts["arc_tolerance"] = float(value)
            if not opts["arc_tolerance"] > 0:
                raise ValueError("kinpost_post: --arc-tolerance must be > 0 mm")
        elif a == "--tool-axis":
            v = tuple(float(x) for x in value.split(","))
            if len(v) != 3:
                raise ValueError("kinpost_post: --tool-axis needs I,J,K")
            opts["tool_axis"] = unit(v)
        else:
            raise ValueError("kinpost_post: unknown argument %s" % a)
        i += 2
    return opts


def unit(v):
    n = math.sqrt(sum(c * c for c in v))
    if n < 1e-12:
        raise ValueError("kinpost_post: zero tool axis")
    return tuple(c / n for c in v)


def fmt(v):
    s = "%.6f" % v
    s = s.rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def arc_points(start, end, center, clockwise, tol):
    """Points (without the start) along an XY arc, chord error <= tol."""
    r = math.hypot(start[0] - center[0], start[1] - center[1])
    a0 = math.atan2(start[1] - center[1], start[0] - center[0])
    a1 = math.atan2(end[1] - center[1], end[0] - center[0])
    sweep = a1 - a0
    if clockwise and sweep >= 0:
        sweep -= 2 * math.pi
    if not clockwise and sweep <= 0:
        sweep += 2 * math.pi
    if r < 1e-9:
        return [end]
    step = 2 * math.acos(max(-1.0, min(1.0, 1 - tol / r))) if tol < r else math.pi / 2
    n = max(1, int(math.ceil(abs(sweep) / max(step, 1e-6))))
    pts = []
    for k in range(1, n + 1):
        t = k / n
        a = a0 + sweep * t
        z = start[2] + (end[2] - start[2]) * t
        pts.append((center[0] + r * math.cos(a), center[1] + r * math.sin(a), z))
    pts[-1] = end
    return pts


def pose_program(commands, opts, header="(FreeCAD job)"):
    """The pose program (a list of lines) for FreeCAD Path commands.

    `commands` is a sequence of objects with `.Name` and `.Parameters`
    (a dict), as FreeCAD's Path.Command has.  Nothing is dropped: a move
    becomes a pose (or several, for an arc), a tool change, spindle,
    coolant or dwell command is written with its words, a comment stays a
    comment, and any other command raises ValueError naming it."""
    out = ["%", header, "G21 G90 G94 G17"]
    commands = list(commands)
    # The tool tip as the moves so far set it, per coordinate (None: not
    # given yet).
    pos = [None, None, None]
    state = {"motion": None, "axis": opts["tool_axis"], "plane": "G17"}
    feed = None
    # ahead[i][k]: the first value of coordinate k that a move from
    # command i on gives (None if none does).
    ahead = [[None, None, None] for _ in range(len(commands) + 1)]
    for i in range(len(commands) - 1, -1, -1):
        ahead[i] = list(ahead[i + 1])
        c = commands[i]
        if normal(c.Name) in MOTION or normal(c.Name) in ARCS:
            p = {k.upper(): v for k, v in c.Parameters.items()}
            for k, axis in enumerate("XYZ"):
                if axis in p:
                    ahead[i][k] = p[axis]

    def emit(g, tip, axis, f):
        out.append(block(g, tip, axis, f, state["motion"]))
        state["motion"] = g

    for idx, c in enumerate(commands):
        if c.Name.startswith("("):
            text = c.Name.strip().strip("()")
            out.append("(" + text.replace("(", "[").replace(")", "]") + ")")
            continue
        name = normal(c.Name)
        p = {k.upper(): v for k, v in c.Parameters.items()}
        if "F" in p:
            # FreeCAD keeps feeds in mm/s internally; G-code wants mm/min.
            feed = p["F"] * 60.0
        if name in MOTION:
            if all(k in p for k in "IJK"):
                state["axis"] = unit((p["I"], p["J"], p["K"]))
            g = "G0" if name == "G0" else "G1"
            f = feed if g == "G1" else None
            for k, ax in enumerate("XYZ"):
                if ax in p:
                    pos[k] = p[ax]
            unknown = [k for k in range(3) if pos[k] is None]
            if unknown:
                # The first moves of a FreeCAD job give one or two
                # coordinates (`G0 Z15`, then `G0 X10 Y10`): the tool
                # starts wherever the tool change left it.  A tool pose
                # needs the whole tip, so the coordinates not given yet are
                # those the next moves give first, said in a comment.
                names = "".join("XYZ"[k] for k in unknown)
                for k in unknown:
                    pos[k] = ahead[idx][k]
                if None in pos:
                    missing = "".join("XYZ"[k] for k in range(3) if pos[k] is None)
                    raise ValueError("kinpost_post: the job never gives %s of the "
                                     "tool tip" % missing)
                out.append("(kinpost_post: %s from the next move that gives %s)"
                           % (names, "it" if len(names) == 1 else "them"))
            emit(g, list(pos), state["axis"], f)
        elif name in ARCS:
            if state["plane"] != "G17" or "R" in p:
                raise ValueError("kinpost_post: %s %s: only arcs in the XY plane (G17) "
                                 "with I J centres are linearised here"
                                 % (c.Name, "with R" if "R" in p else "in " + state["plane"]))
            target = [p.get(k, pos[i]) for i, k in enumerate("XYZ")]
            if None in pos or None in target:
                raise ValueError("kinpost_post: %s before the tool tip is known: "
                                 "give X, Y and Z by a straight move first" % c.Name)
            center = (pos[0] + p.get("I", 0.0), pos[1] + p.get("J", 0.0))
            cw = name == "G2"
            for pt in arc_points(pos, target, center, cw, opts["arc_tolerance"]):
                emit("G1", pt, state["axis"], feed)
            pos = list(target)
        elif name in REFUSED:
            raise ValueError("kinpost_post: %s is %s, which this post does not "
                             "convert into tool poses" % (c.Name, REFUSED[name]))
        elif name in PASS_THROUGH:
            if name in ("G17", "G18", "G19"):
                state["plane"] = name
            words = [name]
            for k in sorted(p, key=word_order):
                if k != "F":  # the feed goes on the next G1
                    words.append(k + fmt(p[k]))
            out.append(" ".join(words))
        else:
            raise ValueError("kinpost_post: unknown command %s %s: not converted; "
                             "nothing is dropped silently" % (c.Name, p))
    out.append("M30")
    out.append("%")
    return out


def normal(name):
    """`G00` → `G0`, `m06` → `M6`: FreeCAD writes both spellings."""
    n = name.strip().upper()
    if len(n) > 1 and n[0] in "GM" and n[1:].replace(".", "", 1).isdigit():
        num = n[1:].lstrip("0") or "0"
        if num.startswith("."):
            num = "0" + num
        return n[0] + num
    return n


def word_order(k):
    """Words after the command: T, H, D, S, P, then the rest alphabetically."""
    return ("THDSP".index(k) if k in "THDSP" else 5, k)


def block(g, tip, axis, feed, motion):
    words = [] if g == motion else [g]
    words += ["X" + fmt(tip[0]), "Y" + fmt(tip[1]), "Z" + fmt(tip[2]),
              "I" + fmt(axis[0]), "J" + fmt(axis[1]), "K" + fmt(axis[2])]
    if feed is not None:
        words.append("F" + fmt(feed))
    return " ".join(words)


def run_kinpost(text, filename, opts):
    if not opts["machine"]:
        raise ValueError("kinpost_post: give --machine FILE|NAME (or set KINPOST_MACHINE)")
    cmd = [opts["kinpost"], "post", "--machine", opts["machine"], "--quiet"]
    if opts["decimals"] is not None:
        cmd += ["--decimals", str(opts["decimals"])]
    cmd += opts["kinpost_args"]
    if filename and filename != "-":
        cmd += ["-o", filename]
    cmd.append("-")
    r = subprocess.run(cmd, input=text.encode("utf-8"), capture_output=True)
    if r.returncode != 0:
        raise RuntimeError(
            "kinpost failed (exit %d):\n%s" % (r.returncode, r.stderr.decode("utf-8", "replace"))
        )
    return r.stdout.decode("utf-8", "replace")


def export(objectslist, filename, argstring):
    """FreeCAD's entry point: post-process `objectslist` into `filename`."""
    opts = parse_args(argstring)
    commands = []
    for obj in objectslist:
        path = getattr(obj, "Path", None)
        if path is None:
            continue
        commands.append(_Comment("(" + getattr(obj, "Label", "operation") + ")"))
        commands.extend(path.Commands)
    text = "\n".join(pose_program(commands, opts)) + "\n"
    if opts["poses_only"]:
        if filename and filename != "-":
            with open(filename, "w", encoding="utf-8") as f:
                f.write(text)
        return text
    result = run_kinpost(text, filename, opts)
    if filename and filename != "-":
        with open(filename, "r", encoding="utf-8", errors="replace") as f:
            return f.read()
    return result


class _Comment:
    def __init__(self, text):
        self.Name = text
        self.Parameters = {}


class _Cmd:
    def __init__(self, name, **params):
        self.Name = name
        self.Parameters = params


def _self_test():
    cmds = [
        _Cmd("G0", X=0.0, Y=0.0, Z=5.0),
        _Cmd("G1", Z=0.0, F=10.0),
        _Cmd("G1", X=10.0, I=0.0, J=0.6, K=0.8),
        _Cmd("G2", X=20.0, Y=0.0, I=5.0, J=0.0),
        _Cmd("G1", X=20.0, Y=5.0),
    ]
    lines = pose_program(cmds, parse_args("--machine m --arc-tolerance 0.01"))
    assert lines[3] == "G0 X0 Y0 Z5 I0 J0 K1", lines[3]
    assert lines[4] == "G1 X0 Y0 Z0 I0 J0 K1 F600", lines[4]
    assert lines[5] == "X10 Y0 Z0 I0 J0.6 K0.8 F600", lines[5]
    arc = [l for l in lines[6:] if l.startswith("X")]
    assert len(arc) > 10 and arc[-2].startswith("X20 Y0 "), arc[-2:]
    for l in arc[:-1]:
        x = float(l.split()[0][1:])
        y = float(l.split()[1][1:])
        assert abs(math.hypot(x - 15.0, y) - 5.0) < 1e-5, l
    print("kinpost_post self-test: ok (%d lines)" % len(lines))


if __name__ == "__main__":
    if sys.argv[1:] == ["--self-test"]:
        _self_test()
    else:
        sys.stderr.write(__doc__ if __doc__ else "kinpost_post.py --self-test\n")
