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

Pinocchio is called from Python; the time of the Python-to-C++ call itself is measured on an
empty model (no joints, same arguments) and subtracted, which leaves an estimate of the C++
time. Both the raw and the corrected ratios are printed (ratio = Pinocchio time / treecal
time: above 1 means treecal is faster). Each figure is taken over many rounds of about 2 ms,
as the median and as the minimum (on a shared machine, the round nobody interrupted);
treecal and Pinocchio are alternated R times (default 3) and the median over alternations
printed, so load from other processes affects both alike.
Requires tests/oracle/requirements.txt. See docs/performance.md.
"""

import json
import os
import statistics
import subprocess
import sys
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
    # The Python-to-C++ call cost: the same calls on a model without joints.
    empty = pin.Model()
    empty.addFrame(pin.Frame("tool", 0, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME))
    empty_data = empty.createData()
    empty_q = [pin.neutral(empty)] * len(qs)
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
    empty_frames = [1] * len(both)
    overhead = {
        "fk_both_tools": timing_ns(rounds, empty_q, fk(empty, empty_data, empty_frames)),
        "fk_one_tool": timing_ns(rounds, empty_q, fk(empty, empty_data, empty_frames[:1])),
        "jacobian_both_tools": timing_ns(rounds, empty_q, regressor(empty, empty_data, empty_frames)),
        "jacobian_one_tool": timing_ns(rounds, empty_q, regressor(empty, empty_data, empty_frames[:1])),
    }
    return model, times, overhead, error


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
    runs = []
    for _ in range(repeat):
        side = treecal_side(robot, rounds, binary)
        runs.append((side, pinocchio_side(side["robot"], side, rounds)))
    side, (model, _, _, error) = runs[-1]
    print("robot: %s" % side["robot"])
    print("tools: %s; MCPC parameters: %d; reduced Pinocchio model: %d joints (nq %d), regressor 6 x %d"
          % (", ".join(side["tools"]), side["parameters"], model.njoints - 1, model.nq, 6 * (model.njoints - 1)))
    print("tool positions, treecal vs Pinocchio: max difference %.1e m" % error)
    print("pinocchio %s, %d configurations, %d rounds x %d alternations (medians)"
          % (pin.__version__, len(side["values"]), rounds, repeat))
    for statistic, which in (("median", 0), ("minimum", 1)):
        print("%s of the rounds:" % statistic)
        print("%-22s %12s %14s %14s %10s %10s" % (
            "operation", "treecal ns", "pinocchio ns", "call cost ns", "ratio raw", "ratio C++"))
        for name in ["fk_both_tools", "fk_one_tool", "jacobian_both_tools", "jacobian_one_tool"]:
            ours = statistics.median(r[0]["ns"][name][which] for r in runs)
            theirs = statistics.median(r[1][1][name][which] for r in runs)
            overhead = statistics.median(r[1][2][name][which] for r in runs)
            print("%-22s %12.1f %14.1f %14.1f %10.2f %10.2f" % (
                name, ours, theirs, overhead, theirs / ours, (theirs - overhead) / ours))
        as_poses = statistics.median(r[0]["ns"]["fk_both_tools_as_poses"][which] for r in runs)
        print("treecal fk_both_tools as Isometry3 poses (quaternions, allocated Vec): %.1f ns" % as_poses)
        iteration = statistics.median(r[0]["ns"]["gn_iteration_200x2"][which] for r in runs)
        print("one Gauss-Newton iteration (%d parameters, 200 configurations x %d tools): %.0f us wall"
              % (side["parameters"], side["tool_count"], iteration / 1e3))
    cpu = statistics.median(r[0]["gn_iteration_cpu"] for r in runs)
    print("one Gauss-Newton iteration, mean CPU time (all threads): %.0f us" % (cpu / 1e3))


if __name__ == "__main__":
    main()
