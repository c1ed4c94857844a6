#!/usr/bin/env python3
"""Peer benchmark: treecal against Pinocchio on the same robot, tools and configurations.

Usage (from the repository root):
    python3 benches/peer/peer.py [ROBOT.urdf] [--rounds N] [--repeat R] [--binary PATH]

--binary runs an already built `target/release/examples/peer` instead of `cargo run`.

Builds and runs `cargo run --release --example peer` (the treecal side: MCPC forward
kinematics of both tools and of one tool, the identification Jacobian of both tools and of
one tool, median ns per call), then times Pinocchio on the same URDF reduced to the joints of
the MCPC chains (every other joint locked at zero, `pin.buildReducedModel`), set to the same
joint values:

* fk:        pin.forwardKinematics + pin.updateFramePlacement of each tool link (treecal:
             `tool_transforms_into`, rotation matrices + translations into reused buffers as
             Pinocchio's frame placements are; `tool_poses`, which converts to quaternions and
             allocates its result, is printed too)
* regressor: the above + pin.computeFrameKinematicRegressor of each tool link (6 x 6*njoints,
             every joint placement's six parameters; treecal's Jacobian has 4 or 2 per frame
             and 6 per tool)

Pinocchio is timed twice. **C++** (the figures to compare): `pinocchio_peer.cpp`, compiled
here with g++ -O3 against the headers and libraries the `pin` wheel ships, makes the same calls
on the same reduced model into preallocated outputs, with no Python in the loop. **Python** (labelled
as such): the calls from Python, which include the binding's own work (argument conversion, and
for the regressor a 6 x 6*njoints copy to numpy per call). The earlier estimate "Python time minus
the call cost on an empty model" missed that binding work and overstated Pinocchio's time; it is no
longer printed. Ratios are Pinocchio time / treecal time: above 1 means treecal is faster. Each
figure is taken over many rounds of about 2 ms, as the median and as the minimum (on a shared
machine, the round nobody interrupted); treecal, Pinocchio C++ and Pinocchio Python are alternated
R times (default 3) and the median over alternations printed, so load from other processes affects
all alike.
Requires tests/oracle/requirements.txt, benches/peer/requirements.txt (Eigen and urdfdom headers
for the C++ side) and g++. See docs/performance.md.
"""

import json
import os
import statistics
import subprocess
import sys
import sysconfig
import tempfile
import time

import numpy as np
import pinocchio as pin

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def treecal_side(robot, rounds, binary):
    command = [binary] if binary else ["cargo", "run", "--quiet", "--release", "--example", "peer", "--"]
    if robot:
        command.append(robot)
    command += ["--rounds", str(rounds)]
    out = subprocess.run(command, cwd=ROOT, check=True, capture_output=True, text=True)
    return json.loads(out.stdout)


def reduced_model(robot, kept_joints):
    full = pin.buildModelFromUrdf(robot, mimic=False)
    locked = [
        j
        for j in range(1, full.njoints)
        if full.names[j] not in kept_joints
    ]
    return pin.buildReducedModel(full, locked, pin.neutral(full))


def configuration(model, joints, values):
    q = pin.neutral(model)
    for name, value in zip(joints, values):
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:  # continuous: (cos, sin)
            q[joint.idx_q] = np.cos(value)
            q[joint.idx_q + 1] = np.sin(value)
        else:
            q[joint.idx_q] = value
    return q


def timing_ns(rounds, qs, call):
    """Median and minimum over `rounds` rounds of about 2 ms of the mean ns per call (on a
    loaded machine the minimum is the round no other process interrupted)."""
    start = time.perf_counter()
    for q in qs:
        call(q)
    once = (time.perf_counter() - start) / len(qs)
    repeats = max(1, int(0.002 / max(once, 1e-9)) // len(qs))
    samples = []
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(repeats):
            for q in qs:
                call(q)
        samples.append((time.perf_counter() - start) * 1e9 / (repeats * len(qs)))
    return [statistics.median(samples), min(samples)]


def pinocchio_side(robot, side, rounds):
    model = reduced_model(robot, set(side["joints"]))
    data = model.createData()
    tools = [model.getFrameId(name) for name in side["tools"]]
    qs = [configuration(model, side["joints"], v) for v in side["values"]]
    # Same robot and tips: the tool positions agree with treecal's.
    error = 0.0
    for q, positions in zip(qs, side["tool_positions"]):
        pin.forwardKinematics(model, data, q)
        for frame, p in zip(tools, positions):
            error = max(error, np.abs(pin.updateFramePlacement(model, data, frame).translation - p).max())
    world = pin.ReferenceFrame.WORLD

    def fk(m, d, frames):
        def call(q):
            pin.forwardKinematics(m, d, q)
            for f in frames:
                pin.updateFramePlacement(m, d, f)
        return call

    def regressor(m, d, frames):
        def call(q):
            pin.forwardKinematics(m, d, q)
            for f in frames:
                pin.updateFramePlacement(m, d, f)
                pin.computeFrameKinematicRegressor(m, d, f, world)
        return call

    both, one = tools, tools[:1]
    times = {
        "fk_both_tools": timing_ns(rounds, qs, fk(model, data, both)),
        "fk_one_tool": timing_ns(rounds, qs, fk(model, data, one)),
        "jacobian_both_tools": timing_ns(rounds, qs, regressor(model, data, both)),
        "jacobian_one_tool": timing_ns(rounds, qs, regressor(model, data, one)),
    }
    return model, times, error


PREFIX = os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix")
CPP_SOURCE = os.path.join(ROOT, "benches", "peer", "pinocchio_peer.cpp")
CPP_BINARY = os.path.join(ROOT, "target", "peer", "pinocchio_peer")


def build_cpp():
    """Compile pinocchio_peer.cpp against the pin wheel (once; again when the source changes)."""
    if os.path.exists(CPP_BINARY) and os.path.getmtime(CPP_BINARY) >= os.path.getmtime(CPP_SOURCE):
        return CPP_BINARY
    os.makedirs(os.path.dirname(CPP_BINARY), exist_ok=True)
    include = os.path.join(PREFIX, "include")
    lib = os.path.join(PREFIX, "lib")
    defines = [
        "PINOCCHIO_WITH_URDFDOM", "PINOCCHIO_URDFDOM_HEADERS_MAJOR_VERSION=3",
        "PINOCCHIO_URDFDOM_HEADERS_MINOR_VERSION=0", "PINOCCHIO_URDFDOM_HEADERS_PATCH_VERSION=0",
        "BOOST_MPL_LIMIT_LIST_SIZE=30", "BOOST_MPL_LIMIT_VECTOR_SIZE=30",
        "BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "BOOST_FUSION_INVOKE_MAX_ARITY=12",
    ]
    command = (
        ["g++", "-O3", "-DNDEBUG", "-std=c++17", "-w"]
        + ["-I" + os.path.join(include, d) for d in ("", "eigen3", "urdfdom_headers")]
        + ["-D" + d for d in defines]
        + [CPP_SOURCE, "-o", CPP_BINARY, "-L" + lib, "-Wl,-rpath," + lib]
        + ["-l" + l for l in ("pinocchio_parsers", "pinocchio_default", "urdfdom_model",
                              "boost_filesystem", "boost_serialization")]
    )
    print("building the C++ side (a few minutes, once): %s" % " ".join(command[:6]), file=sys.stderr)
    subprocess.run(command, check=True)
    return CPP_BINARY


def pinocchio_cpp_side(binary, side, rounds):
    """Times of the C++ calls ({operation: [median, minimum]}) and its tool position error."""
    with tempfile.NamedTemporaryFile("w", suffix=".txt", delete=False) as f:
        f.write("urdf %s\n" % side["robot"])
        f.write("joints %s\n" % " ".join(side["joints"]))
        f.write("tools %s\n" % " ".join(side["tools"]))
        f.write("rounds %d\n" % rounds)
        for values, positions in zip(side["values"], side["tool_positions"]):
            numbers = list(values) + [c for p in positions for c in p]
            f.write("config %s\n" % " ".join(repr(float(v)) for v in numbers))
        path = f.name
    try:
        out = subprocess.run([binary, path], check=True, capture_output=True, text=True).stdout
    finally:
        os.unlink(path)
    times, error = {}, None
    for line in out.splitlines():
        words = line.split()
        if words[0] == "max_position_error":
            error = float(words[1])
        elif words[0] != "model":
            times[words[0]] = [float(words[1]), float(words[2])]
    return times, error


def main():
    robot, rounds, repeat, binary = None, 101, 3, None
    args = sys.argv[1:]
    while args:
        arg = args.pop(0)
        if arg == "--rounds":
            rounds = int(args.pop(0))
        elif arg == "--repeat":
            repeat = int(args.pop(0))
        elif arg == "--binary":
            binary = os.path.abspath(args.pop(0))
        else:
            robot = os.path.abspath(arg)
    binary_cpp = build_cpp()
    runs = []
    for _ in range(repeat):
        side = treecal_side(robot, rounds, binary)
        cpp_times, cpp_error = pinocchio_cpp_side(binary_cpp, side, rounds)
        model, py_times, py_error = pinocchio_side(side["robot"], side, rounds)
        runs.append((side, cpp_times, py_times))
    side = runs[-1][0]
    print("robot: %s" % side["robot"])
    print("tools: %s; MCPC parameters: %d; reduced Pinocchio model: %d joints (nq %d), regressor 6 x %d"
          % (", ".join(side["tools"]), side["parameters"], model.njoints - 1, model.nq, 6 * (model.njoints - 1)))
    print("tool positions, treecal vs Pinocchio: max difference %.1e m (C++), %.1e m (Python)"
          % (cpp_error, py_error))
    print("pinocchio %s, %d configurations, %d rounds x %d alternations (medians)"
          % (pin.__version__, len(side["values"]), rounds, repeat))
    for statistic, which in (("median", 0), ("minimum", 1)):
        print("%s of the rounds:" % statistic)
        print("%-22s %12s %14s %14s %11s %14s" % (
            "operation", "treecal ns", "pinocchio C++", "ratio C++", "pin Python", "ratio Python"))
        for name in ["fk_both_tools", "fk_one_tool", "jacobian_both_tools", "jacobian_one_tool"]:
            ours = statistics.median(r[0]["ns"][name][which] for r in runs)
            cpp = statistics.median(r[1][name][which] for r in runs)
            python = statistics.median(r[2][name][which] for r in runs)
            print("%-22s %12.1f %14.1f %14.2f %11.1f %14.2f" % (
                name, ours, cpp, cpp / ours, python, python / ours))
        as_poses = statistics.median(r[0]["ns"]["fk_both_tools_as_poses"][which] for r in runs)
        print("treecal fk_both_tools as Isometry3 poses (quaternions, allocated Vec): %.1f ns" % as_poses)
        allocating = statistics.median(r[0]["ns"]["jacobian_both_tools_allocating"][which] for r in runs)
        print("treecal jacobian_both_tools allocating its matrices (tool_jacobians): %.1f ns" % allocating)
        iteration = statistics.median(r[0]["ns"]["gn_iteration_200x2"][which] for r in runs)
        print("one Gauss-Newton iteration (%d parameters, 200 configurations x %d tools): %.0f us wall"
              % (side["parameters"], side["tool_count"], iteration / 1e3))
    cpu = statistics.median(r[0]["gn_iteration_cpu"] for r in runs)
    print("one Gauss-Newton iteration, mean CPU time (all threads): %.0f us" % (cpu / 1e3))


if __name__ == "__main__":
    main()
