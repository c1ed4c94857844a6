#!/usr/bin/env python3
"""Independent recomputation of `treecal verify` figures with Pinocchio (tests/verify.rs).

Usage: verify_points.py URDF LINK CSV [--registration FILE] [--fit-frame]

Reads a treecal measurement CSV (`x,y,z` single targets or `ax..cz` three targets; the
`# units:` comment), places the URDF (parsed by Pinocchio) at the registration (treecal's
YAML: units, xyz, rpy), or fits the frame tracker_from_root by Gauss-Newton on the positions
(--fit-frame, started from the registration or the centroids), and prints one line per row:
`id position_error_mm` (repr, full precision), then `rms RMS`.
"""
import csv
import math
import re
import sys

import numpy as np
import pinocchio as pin

SCALE = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "rad": 1.0, "deg": math.pi / 180}


def read_rows(path):
    units = {"length": "m", "angle": "rad", "joint_length": None}
    header, rows = None, []
    with open(path, encoding="utf-8-sig") as f:
        for line in f:
            s = line.strip()
            if not s:
                continue
            if s.startswith("#"):
                if s.lstrip("# ").startswith("units:"):
                    for tok in s.split("units:", 1)[1].split():
                        k, _, v = tok.partition("=")
                        units[k] = v
                continue
            cells = [c.strip() for c in next(csv.reader([s]))]
            if header is None:
                header = cells
            else:
                rows.append(dict(zip(header, cells)))
    return rows, units


def read_registration(path):
    text = open(path).read()

    def vec(key):
        m = re.search(rf"^{key}:\s*\[([^\]]*)\]", text, re.M)
        return [float(v) for v in m.group(1).split(",")]

    lu = re.search(r"length:\s*(\w+)", text).group(1)
    au = re.search(r"angle:\s*(\w+)", text).group(1)
    xyz = np.array(vec("xyz")) * SCALE[lu]
    rpy = np.array(vec("rpy")) * SCALE[au]
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)


def link_poses(model, data, frame, rows, units):
    angle, length = SCALE[units["angle"]], SCALE[units["length"]]
    joint_length = SCALE[units["joint_length"] or units["length"]]
    poses = []
    for r in rows:
        q = pin.neutral(model)
        for j in range(1, model.njoints):
            name = model.names[j]
            if name not in r:
                continue
            jt = model.joints[j]
            v = float(r[name])
            v *= joint_length if jt.shortname().startswith("JointModelP") else angle
            if jt.nq == 2:
                q[jt.idx_q], q[jt.idx_q + 1] = math.cos(v), math.sin(v)
            else:
                q[jt.idx_q] = v
        pin.framesForwardKinematics(model, data, q)
        poses.append(data.oMf[frame].copy())
    return poses


def measured_points(rows, units):
    scale = SCALE[units["length"]]
    key = "" if "x" in rows[0] else "a"
    return np.array([[float(r[key + c]) for c in "xyz"] for r in rows]) * scale


def fit(poses, points, frame):
    for _ in range(100):
        predicted = np.array([(frame * p).translation for p in poses])
        residual = (points - predicted).reshape(-1)
        jacobian = np.zeros((3 * len(poses), 6))
        for i, p in enumerate(predicted):
            # d(exp(δ)·x)/dδ at δ = 0: [I, -[x]×]
            jacobian[3 * i:3 * i + 3, :3] = np.eye(3)
            jacobian[3 * i:3 * i + 3, 3:] = -pin.skew(p)
        step = np.linalg.lstsq(jacobian, residual, rcond=None)[0]
        frame = pin.exp6(pin.Motion(step)) * frame
        if np.linalg.norm(step) < 1e-15:
            break
    return frame


def main():
    args = sys.argv[1:]
    urdf, link, path = args[:3]
    registration = args[args.index("--registration") + 1] if "--registration" in args else None
    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    rows, units = read_rows(path)
    poses = link_poses(model, data, model.getFrameId(link), rows, units)
    points = measured_points(rows, units)
    frame = read_registration(registration) if registration else pin.SE3.Identity()
    if "--fit-frame" in args:
        if registration is None:
            start = np.array([p.translation for p in poses]).mean(0)
            frame = pin.SE3(np.eye(3), points.mean(0) - start)
        frame = fit(poses, points, frame)
    errors = [np.linalg.norm((frame * p).translation - x) * 1e3 for p, x in zip(poses, points)]
    for r, e in zip(rows, errors):
        print(r.get("id", "?"), repr(float(e)))
    print("rms", repr(math.sqrt(sum(e * e for e in errors) / len(errors))))


if __name__ == "__main__":
    main()
