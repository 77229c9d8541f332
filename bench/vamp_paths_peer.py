"""VAMP's path lengths on the MotionBenchMaker problems, before and after its simplification.

Usage: python vamp_paths_peer.py ROBOT PROBLEMS.pkl [--dump FILE]
Run with the interpreter of the VAMP peer's virtualenv (`../shared/peers/vamp/side_by_side.sh`
makes it, by default under /tmp/vamp-peer-venv). Plans every problem VAMP treats as valid as
the peer script does (RRT-Connect, default settings, the Halton sequence reset per problem),
simplifies with VAMP's default settings, and prints per set
  RESULT vamp_paths set=<set>_<robot> solved= raw_length_median= length_median=
         waypoints_median= simplify_median_ms=
The lengths are sums of the Euclidean joint-space distances between waypoints (VAMP's
`Path.cost()`), beside `ember-bench plan`'s `raw_length_median` and `length_median` (the same
sums, continuous joints measured the short way round).
With --dump, each solved problem's simplified path (VAMP's answer) goes to FILE, one JSON object
a line, as `ember-bench plan --paths-out` writes Ember's: {"set": "<set>_<robot>", "index",
"joints", "path"}, for `bench/path_truth.py`.
"""
import json
import pickle
import statistics as st
import sys

import vamp


# The joints of VAMP's configurations, in its order (the MotionBenchMaker groups').
JOINTS = {
    "fetch": ["torso_lift_joint", "shoulder_pan_joint", "shoulder_lift_joint",
              "upperarm_roll_joint", "elbow_flex_joint", "forearm_roll_joint", "wrist_flex_joint",
              "wrist_roll_joint"],
    "panda": [f"panda_joint{i}" for i in range(1, 8)],
}


def main():
    robot, pkl = sys.argv[1], sys.argv[2]
    dump = open(sys.argv[sys.argv.index("--dump") + 1], "w") if "--dump" in sys.argv else None
    problems = pickle.load(open(pkl, "rb"))
    vmod, planner, plan_settings, simp_settings = vamp.configure_robot_and_planner_with_kwargs(
        robot, "rrtc")
    sampler = vmod.halton()
    for name, pset in problems["problems"].items():
        raw, length, waypoints, ms = [], [], [], []
        for k, data in enumerate(pset):
            if not data["valid"]:
                continue
            env = vamp.problem_dict_to_vamp(data)
            sampler.reset()
            r = planner(data["start"], data["goals"], env, plan_settings, sampler)
            if not r.solved:
                continue
            s = vmod.simplify(r.path, env, simp_settings, sampler)
            raw.append(r.path.cost())
            length.append(s.path.cost())
            waypoints.append(len(s.path))
            ms.append(s.nanoseconds / 1e6)
            if dump:
                # By index: the path type has no bounds-checked iteration.
                path = [[float(v) for v in s.path[i]] for i in range(len(s.path))]
                dump.write(json.dumps({"set": f"{name}_{robot}", "index": data.get("index", k + 1),
                                       "joints": JOINTS[robot], "path": path}) + "\n")
        if not raw:
            continue
        print(f"RESULT vamp_paths set={name}_{robot} solved={len(raw)} "
              f"raw_length_median={st.median(raw):.3f} length_median={st.median(length):.3f} "
              f"waypoints_median={st.median(waypoints):.0f} simplify_median_ms={st.median(ms):.4f}")
    if dump:
        dump.close()


if __name__ == "__main__":
    main()
