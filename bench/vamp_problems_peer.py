"""VAMP's RRT-Connect on chosen MotionBenchMaker problems, one line per problem.

Usage: python vamp_problems_peer.py ROBOT PROBLEMS.pkl SET INDEX[,INDEX...] [--pointcloud]
Run with the interpreter of the VAMP peer's virtualenv (`../shared/peers/vamp/side_by_side.sh`
makes it, by default under /tmp/vamp-peer-venv). Plans each named problem of SET (the pickle's
set name, e.g. bookshelf_thin) that VAMP treats as valid with VAMP's default settings and the
Halton sequence reset per problem, as the peer script does, and prints
  PROBLEM set=<set> index=<n> solved=<0|1> iterations= tree_nodes= us=
then
  RESULT vamp_problems set=<set> n= iterations= us=
(totals over the problems planned). With --pointcloud, VAMP plans against the point cloud its
own tools sample from each scene (its CAPT mode, with the parameters of the peer's
`vamp_mbm.py --pointcloud-dir`, whose clouds `ember-bench plan --clouds` reads). Under callgrind, the instructions of VAMP's planner call
divided by the iterations give its cost per iteration beside `ember-bench plan --per-problem`
on the same problems (see the README's "MotionBenchMaker, side by side with VAMP").
"""
import pickle
import sys

import vamp


def main():
    robot, pkl, set_name = sys.argv[1], sys.argv[2], sys.argv[3]
    wanted = {int(i) for i in sys.argv[4].split(",")}
    pointcloud = "--pointcloud" in sys.argv[5:]
    problems = pickle.load(open(pkl, "rb"))
    vmod, planner, settings, _ = vamp.configure_robot_and_planner_with_kwargs(robot, "rrtc")
    sampler = vmod.halton()
    if pointcloud:
        from vamp import pointcloud as vpc

        r_min, r_max = vmod.min_max_radii()
    total_iterations, total_us, n = 0, 0.0, 0
    for k, data in enumerate(problems["problems"][set_name]):
        index = data.get("index", k + 1)
        if index not in wanted or not data["valid"]:
            continue
        if pointcloud:
            # 10,000 points per object, filtered at 2 cm, culled to the robot's reach.
            env = vpc.problem_dict_to_pointcloud(robot, r_min, r_max, data, 10000, 0.02, True)[0]
        else:
            env = vamp.problem_dict_to_vamp(data)
        sampler.reset()
        r = planner(data["start"], data["goals"], env, settings, sampler)
        us = r.nanoseconds / 1e3
        print(f"PROBLEM set={set_name} index={index} solved={int(r.solved)} "
              f"iterations={r.iterations} tree_nodes={sum(r.size)} us={us:.1f}")
        total_iterations += r.iterations
        total_us += us
        n += 1
    print(f"RESULT vamp_problems set={set_name} n={n} iterations={total_iterations} us={total_us:.1f}")


if __name__ == "__main__":
    main()
