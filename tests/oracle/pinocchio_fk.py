#!/usr/bin/env python3
"""Independent forward-kinematics oracle for treecal, built on Pinocchio.

Usage:
    python3 tests/oracle/pinocchio_fk.py ROBOT.urdf < request.json > response.json
    python3 tests/oracle/pinocchio_fk.py --batch < batch.json > responses.json
      (batch.json: {"robots": [{"urdf": PATH, "links": ..., "configurations": ...}]},
       responses.json: {"results": [{"poses": ...}, ...]}, one per robot, in order)

request.json:
    {"links": ["link_a", ...],
     "configurations": [{"joint_name": value, ...}, ...]}
  Values are keyed by URDF joint name: radians for revolute/continuous,
  metres for prismatic.  Joints that are not named are at 0.

response.json:
    {"poses": [{"link_a": [16 floats], ...}, ...]}
  One object per configuration; each value is the 4x4 homogeneous transform
  root_from_link (pose of the link frame in the URDF root link frame),
  row-major, printed with Python's float repr (round-trip exact).

Any error (bad usage, unreadable/invalid URDF, unknown link or joint name,
bad value) prints a message on stderr and exits with a non-zero status;
nothing is written on stdout in that case.

Requires the PyPI package `pin` (Pinocchio); see requirements.txt beside
this file.  Notes on how the URDF is interpreted by Pinocchio (checked with
pin 4.1.0):

* Kinematics only: the model is built with pinocchio.buildModelFromUrdf,
  never the geometry/collision models, so missing `package://` meshes do not
  matter.
* Fixed base: buildModelFromUrdf without a root_joint argument attaches the
  URDF root link rigidly to Pinocchio's "universe" (joint 0), with an
  identity placement.  Poses are nevertheless computed relative to the
  root link's own BODY frame (inverse(oMf[root]) * oMf[link]), which is
  exact when that placement is the identity and stays correct otherwise.
* Mimic joints: buildModelFromUrdf(..., mimic=False) (passed explicitly)
  parses a joint carrying <mimic> as an ordinary, independent joint with its
  own configuration entry; the <mimic> relation is neither enforced nor is the
  joint dropped.  (mimic=True would instead make it a JointModelMimic with
  nq=0, i.e. not settable.)  The caller computes and passes every mimic
  joint's value itself; this script checks each one independently against
  the <mimic> element (value = multiplier * master + offset) and fails on a
  mismatch.
* Continuous joints are Pinocchio "unbounded" revolute joints with nq=2 and
  configuration (cos q, sin q); we write both entries.
* Non-unit axes (e.g. `0 0 2`): Pinocchio normalises the URDF axis (a
  revolute `0 0 2` becomes a RevoluteUnaligned joint with axis (0,0,1), a
  prismatic `0 0 -3` moves by q metres along (0,0,-1)), which matches the
  URDF convention, so no preprocessing of the URDF text is needed.  As a
  guard against a future Pinocchio changing that, every joint model that
  exposes its axis is checked to be unit length after loading.
* Joint limits are ignored (forwardKinematics does not clamp).
* Fixed joints have no degree of freedom: naming one in a configuration is an
  error.  Floating and planar joints are left at their neutral (identity)
  configuration and cannot be set through this interface: naming one is an
  error.
"""

import json
import math
import os
import sys
import xml.etree.ElementTree as ET


# The robot being computed, named in errors (batch mode).
CURRENT = {"urdf": None}


def fail(msg, code=2):
    if CURRENT["urdf"]:
        msg = "%s: %s" % (CURRENT["urdf"], msg)
    sys.stderr.write("pinocchio_fk: error: %s\n" % msg)
    sys.exit(code)


class _StdoutToStderr:
    """Redirect OS-level fd 1 to fd 2 so that anything the C++ side
    (urdfdom / console_bridge / Pinocchio) prints cannot corrupt the JSON
    written on stdout."""

    def __enter__(self):
        sys.stdout.flush()
        self.saved = os.dup(1)
        os.dup2(2, 1)
        return self

    def __exit__(self, *exc):
        sys.stdout.flush()
        os.dup2(self.saved, 1)
        os.close(self.saved)
        return False


def read_urdf_structure(path):
    """Independently parse the URDF to know its link names, joint names and
    types, and its root link."""
    try:
        tree = ET.parse(path)
    except (OSError, ET.ParseError) as e:
        fail("cannot read URDF %r: %s" % (path, e))
    robot = tree.getroot()
    if robot.tag != "robot":
        fail("%r is not a URDF file (root element <%s>, expected <robot>)" % (path, robot.tag))
    links = [l.get("name") for l in robot.findall("link")]
    joint_types = {}
    children = set()
    for j in robot.findall("joint"):
        joint_types[j.get("name")] = j.get("type")
        c = j.find("child")
        if c is not None:
            children.add(c.get("link"))
    roots = [l for l in links if l not in children]
    if len(roots) != 1:
        fail("URDF %r must have exactly one root link, found %r" % (path, roots))
    return set(links), joint_types, roots[0]


def read_mimics(path):
    """{joint: (master, multiplier, offset)} for every <mimic> whose master joint exists
    (urdfdom ignores a mimic of a missing joint; so does treecal)."""
    robot = ET.parse(path).getroot()
    names = {j.get("name") for j in robot.findall("joint")}
    mimics = {}
    for j in robot.findall("joint"):
        m = j.find("mimic")
        if m is not None and m.get("joint") in names:
            mimics[j.get("name")] = (
                m.get("joint"),
                float(m.get("multiplier", "1")),
                float(m.get("offset", "0")),
            )
    return mimics


def check_mimics(mimics, ci, cfg):
    """The caller computes mimic joints' values; check them independently:
    value = multiplier * master + offset (URDF convention)."""
    for jname, (master, multiplier, offset) in mimics.items():
        if jname in cfg and master in cfg:
            expected = multiplier * float(cfg[master]) + offset
            if abs(float(cfg[jname]) - expected) > 1e-9 * (1.0 + abs(expected)):
                fail(
                    "configuration %d: mimic joint %r = %r, but %r * %r + %r = %r"
                    % (ci, jname, cfg[jname], multiplier, cfg[master], offset, expected)
                )


def main():
    if len(sys.argv) == 2 and sys.argv[1] == "--batch":
        batch()
        return
    if len(sys.argv) != 2:
        fail("usage: python3 pinocchio_fk.py ROBOT.urdf < request.json > response.json\n"
             "       python3 pinocchio_fk.py --batch < batch.json > responses.json")
    urdf_path = sys.argv[1]

    # ---- request -------------------------------------------------------
    try:
        request = json.load(sys.stdin)
    except (ValueError, UnicodeDecodeError) as e:
        fail("invalid request JSON on stdin: %s" % e)
    write({"poses": poses_for(urdf_path, request)})


def batch():
    """Many robots in one process (Pinocchio's import dominates a single call's time):
    stdin {"robots": [{"urdf": PATH, "links": [...], "configurations": [...]}, ...]},
    stdout {"results": [{"poses": [...]}, ...]} in the same order."""
    try:
        request = json.load(sys.stdin)
    except (ValueError, UnicodeDecodeError) as e:
        fail("invalid request JSON on stdin: %s" % e)
    robots = request.get("robots") if isinstance(request, dict) else None
    if not isinstance(robots, list) or not all(isinstance(r, dict) for r in robots):
        fail('batch request must be {"robots": [{"urdf": ..., "links": ..., "configurations": ...}]}')
    results = []
    for robot in robots:
        urdf_path = robot.get("urdf")
        if not isinstance(urdf_path, str):
            fail('every batch entry needs a "urdf" path')
        CURRENT["urdf"] = urdf_path
        results.append({"poses": poses_for(urdf_path, robot)})
        CURRENT["urdf"] = None
    write({"results": results})


def write(response):
    try:
        text = json.dumps(response, allow_nan=False)
    except ValueError as e:
        fail("non-finite number in result: %s" % e)
    sys.stdout.write(text + "\n")
    sys.stdout.flush()


def poses_for(urdf_path, request):
    """Root_from_link of every requested link at every requested configuration."""
    if not os.path.isfile(urdf_path):
        fail("URDF file not found: %r" % urdf_path)
    if not isinstance(request, dict):
        fail("request must be a JSON object")
    links = request.get("links")
    configs = request.get("configurations")
    if not isinstance(links, list) or not all(isinstance(l, str) for l in links):
        fail('request "links" must be a list of strings')
    if not isinstance(configs, list) or not all(isinstance(c, dict) for c in configs):
        fail('request "configurations" must be a list of objects')

    link_names, joint_types, root_link = read_urdf_structure(urdf_path)

    import numpy as np

    try:
        import pinocchio as pin
    except ImportError as e:
        fail("cannot import pinocchio (pip install pin): %s" % e)

    # ---- model -----------------------------------------------------------
    with _StdoutToStderr():
        try:
            # mimic=False: mimic joints are ordinary independent joints
            # (see module docstring).
            model = pin.buildModelFromUrdf(urdf_path, False)
        except Exception as e:  # Pinocchio raises ValueError/RuntimeError
            fail("Pinocchio cannot load URDF %r: %s" % (urdf_path, e))
    data = model.createData()
    BODY = pin.FrameType.BODY

    # Guard: every axis Pinocchio exposes must be unit length (URDF axes are
    # normalised by consumers; Pinocchio 4.1 does this itself).
    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        try:
            axis = np.asarray(jm.extract().axis, dtype=float)
        except Exception:
            continue  # aligned joint types (RX, RUBZ, ...) have no axis member
        if abs(np.linalg.norm(axis) - 1.0) > 1e-12:
            fail(
                "Pinocchio kept non-unit axis %r for joint %r; this oracle "
                "relies on Pinocchio normalising URDF axes" % (axis.tolist(), model.names[jid])
            )

    for l in [root_link] + links:
        if l not in link_names:
            fail("unknown link %r (not in URDF)" % l)
        if not model.existFrame(l, BODY):
            fail("link %r has no BODY frame in the Pinocchio model" % l)
    root_fid = model.getFrameId(root_link, BODY)
    frame_ids = [model.getFrameId(l, BODY) for l in links]

    # joint name -> (q index, kind) for movable 1-dof URDF joints.
    joint_slots = {}
    for jid in range(1, model.njoints):
        name = model.names[jid]
        jm = model.joints[jid]
        if jm.nv == 1 and jm.nq == 1:
            joint_slots[name] = (jm.idx_q, "scalar")
        elif jm.nv == 1 and jm.nq == 2:
            # continuous: unbounded revolute, q = (cos theta, sin theta)
            joint_slots[name] = (jm.idx_q, "cos_sin")
        else:
            joint_slots[name] = (jm.idx_q, "unsupported:" + jm.shortname())

    q0 = pin.neutral(model)

    # ---- forward kinematics ------------------------------------------------
    poses = []
    mimics = read_mimics(urdf_path)
    for ci, cfg in enumerate(configs):
        check_mimics(mimics, ci, cfg)
        q = q0.copy()
        for jname, value in cfg.items():
            if jname not in joint_types:
                fail("configuration %d: unknown joint %r (not in URDF)" % (ci, jname))
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                fail("configuration %d: joint %r value must be a number, got %r" % (ci, jname, value))
            value = float(value)
            if not math.isfinite(value):
                fail("configuration %d: joint %r value is not finite" % (ci, jname))
            if joint_types[jname] == "fixed":
                fail("configuration %d: joint %r is fixed and has no value" % (ci, jname))
            slot = joint_slots.get(jname)
            if slot is None:
                fail("configuration %d: joint %r is not a joint of the Pinocchio model" % (ci, jname))
            idx, kind = slot
            if kind == "scalar":
                q[idx] = value
            elif kind == "cos_sin":
                q[idx] = math.cos(value)
                q[idx + 1] = math.sin(value)
            else:
                fail(
                    "configuration %d: joint %r (URDF type %r, Pinocchio %s) cannot be set "
                    "with one value" % (ci, jname, joint_types[jname], kind.split(":", 1)[1])
                )
        with _StdoutToStderr():
            pin.framesForwardKinematics(model, data, q)
        root_inv = data.oMf[root_fid].inverse()
        out = {}
        for lname, fid in zip(links, frame_ids):
            T = np.asarray((root_inv * data.oMf[fid]).homogeneous, dtype=float)
            # Guard (covers joint types that do not expose their axis, e.g.
            # continuous with an unaligned axis): a non-normalised axis
            # would give a non-orthonormal rotation.
            R = T[:3, :3]
            if not np.allclose(R.T @ R, np.eye(3), rtol=0.0, atol=1e-9):
                fail("configuration %d: non-orthonormal rotation for link %r" % (ci, lname))
            out[lname] = [float(x) for x in T.reshape(16)]  # row-major
        poses.append(out)
    return poses


if __name__ == "__main__":
    main()
