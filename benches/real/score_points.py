#!/usr/bin/env python3
"""Independent scorer for treecal outputs on point data (e.g. TIAGo BL), with Pinocchio.

Not run by CI: a tool to reproduce the real-data figures of the closing notes and README, e.g.
  python3 benches/real/score_points.py --urdf out/calibrated.urdf --link wrist_ft_tool_link_marker \
      --registration out/registration.yaml --csv VALIDATION.csv
where VALIDATION.csv concatenates the three held-out sessions of ../shared/data/tiago_qualisys/data
(*_three.csv or *_pos1.csv: the first file's comment and header lines, then every data row).

Scores a URDF (as written, parsed by Pinocchio) on a treecal measurement CSV:
    p_measured ≈ tracker_from_root · root_from_link(q) · offset
Position columns: x,y,z (single target) or ax,ay,az (target A of a three-target row).

  --registration FILE   treecal registration YAML (units, xyz, rpy: the root in the tracker frame)
  --fit-frame           fit tracker_from_root (6 DoF) by least squares on --fit-csv (default: --csv)
  --fit-offset          also fit the point offset in --link on --fit-csv
  --joint-errors FILE   treecal joint_errors.yaml: harmonic terms added to the joint angles
Without --registration / --fit-frame the URDF root is taken as the tracker frame.

Verified: registered nominal URDF (fit frame+offset on 2021-11-30 pos1, score 184 rows) = 4.570 mm;
today's main: calibrated.urdf + the registration from report.json "measurement_frame" (xyz m, rpy rad,
written as a registration YAML) = 3.030 mm (three) / 3.879 mm (pos1), offset 0 (tool origin = A/BL).

Examples:
  score_tiago.py --urdf out/calibrated.urdf --csv /tmp/tg/val_three.csv
  score_tiago.py --urdf tiago.urdf --csv val.csv --fit-csv train.csv --fit-frame --fit-offset
"""
import argparse
import csv
import math
import sys

import numpy as np
import pinocchio as pin


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
            cells = next(csv.reader([s]))
            if header is None:
                header = [c.strip() for c in cells]
            else:
                rows.append(dict(zip(header, [c.strip() for c in cells])))
    return header, rows, units


def scale(unit):
    return {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "rad": 1.0, "deg": math.pi / 180}[unit]


def rpy_matrix(r, p, y):
    return pin.rpy.rpyToMatrix(r, p, y)


def read_registration(path):
    import re
    text = open(path).read()
    def vec(key):
        m = re.search(rf"^{key}:\s*\[([^\]]*)\]", text, re.M)
        return [float(v) for v in m.group(1).split(",")]
    lu = re.search(r"length:\s*(\w+)", text).group(1)
    au = re.search(r"angle:\s*(\w+)", text).group(1)
    xyz = np.array(vec("xyz")) * scale(lu)
    rpy = np.array(vec("rpy")) * scale(au)
    return pin.SE3(rpy_matrix(*rpy), xyz)


class Scorer:
    def __init__(self, urdf, link):
        self.model = pin.buildModelFromUrdf(urdf)
        self.data = self.model.createData()
        if not self.model.existFrame(link):
            sys.exit(f"score: no frame {link} in {urdf}")
        self.frame = self.model.getFrameId(link)

    def link_poses(self, rows, units, joint_errors=None):
        ls, as_ = scale(units["length"]), scale(units["angle"])
        js = scale(units["joint_length"] or units["length"])
        poses, points = [], []
        for r in rows:
            q = pin.neutral(self.model)
            for j in range(1, self.model.njoints):
                name = self.model.names[j]
                if name in r:
                    jt = self.model.joints[j]
                    v = float(r[name])
                    if joint_errors and name in joint_errors:
                        e = joint_errors[name]
                        v_rad = v * as_
                        v += (e.get("sine", 0.0) * math.sin(v_rad) + e.get("cosine", 0.0) * math.cos(v_rad)) / as_
                    if jt.shortname().startswith("JointModelP"):
                        v *= js
                    else:
                        v *= as_
                    if jt.nq == 2:  # continuous
                        q[jt.idx_q], q[jt.idx_q + 1] = math.cos(v), math.sin(v)
                    else:
                        q[jt.idx_q] = v
            pin.framesForwardKinematics(self.model, self.data, q)
            poses.append(self.data.oMf[self.frame].copy())
            key = "x" if "x" in r else "ax"
            pre = "" if key == "x" else "a"
            points.append(np.array([float(r[pre + c]) for c in "xyz"]) * ls)
        return poses, np.array(points)


def read_joint_errors(path):
    """joint_errors.yaml (units rad): {joint: {sine, cosine}}; backlash needs torques: refused."""
    import re
    out = {}
    for line in open(path):
        m = re.match(r"^\s+(\S+):\s*\{(.*)\}", line)
        if not m:
            continue
        terms = dict((k.strip(), float(v)) for k, v in (t.split(":") for t in m.group(2).split(",")))
        if terms.get("backlash", 0.0) != 0.0:
            sys.exit("score: backlash terms are not supported here")
        out[m.group(1)] = terms
    return out


def predict(frame, poses, offset):
    return np.array([(frame * P).act(offset) for P in poses])


def fit(poses, points, frame, offset, fit_frame, fit_offset):
    for _ in range(30):
        pred = predict(frame, poses, offset)
        r = (points - pred).reshape(-1)
        cols = []
        if fit_frame:
            for k in range(6):
                d = np.zeros(6); d[k] = 1e-7
                f2 = pin.exp6(pin.Motion(d)) * frame
                cols.append(((predict(f2, poses, offset) - pred) / 1e-7).reshape(-1))
        if fit_offset:
            for k in range(3):
                o2 = offset.copy(); o2[k] += 1e-7
                cols.append(((predict(frame, poses, o2) - pred) / 1e-7).reshape(-1))
        J = np.array(cols).T
        step = np.linalg.lstsq(J, r, rcond=None)[0]
        i = 0
        if fit_frame:
            frame = pin.exp6(pin.Motion(step[:6])) * frame
            i = 6
        if fit_offset:
            offset = offset + step[i:i + 3]
        if np.linalg.norm(step) < 1e-12:
            break
    return frame, offset


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--urdf", required=True)
    ap.add_argument("--csv", required=True, help="rows to score")
    ap.add_argument("--link", default="wrist_ft_tool_link")
    ap.add_argument("--offset", default="0,0,0", help="point in --link, metres")
    ap.add_argument("--registration")
    ap.add_argument("--fit-frame", action="store_true")
    ap.add_argument("--fit-offset", action="store_true")
    ap.add_argument("--fit-csv")
    ap.add_argument("--rows", action="store_true", help="print every row's error")
    ap.add_argument("--joint-errors", help="treecal joint_errors.yaml (harmonics; backlash is refused)")
    a = ap.parse_args()
    s = Scorer(a.urdf, a.link)
    offset = np.array([float(v) for v in a.offset.split(",")])
    frame = read_registration(a.registration) if a.registration else pin.SE3.Identity()
    if a.fit_frame or a.fit_offset:
        _, rows, units = read_rows(a.fit_csv or a.csv)
        poses, points = s.link_poses(rows, units)
        if a.fit_frame and not a.registration:
            # closed-form-ish start: translation from centroids
            c = points.mean(0) - predict(frame, poses, offset).mean(0)
            frame = pin.SE3(np.eye(3), c)
        frame, offset = fit(poses, points, frame, offset, a.fit_frame, a.fit_offset)
        fr = predict(frame, poses, offset) - points
        print(f"fit on {a.fit_csv or a.csv}: n={len(points)} RMS {1e3*math.sqrt((fr**2).sum(1).mean()):.3f} mm; offset {offset}")
    _, rows, units = read_rows(a.csv)
    poses, points = s.link_poses(rows, units, read_joint_errors(a.joint_errors) if a.joint_errors else None)
    e = np.linalg.norm(predict(frame, poses, offset) - points, axis=1) * 1e3
    if a.rows:
        for r, v in zip(rows, e):
            print(r.get("id", "?"), f"{v:.3f}")
    print(f"score {a.csv}: n={len(e)} RMS {math.sqrt((e**2).mean()):.3f} mm, mean {e.mean():.3f}, max {e.max():.3f} (row {rows[int(e.argmax())].get('id','?')})")


if __name__ == "__main__":
    main()
