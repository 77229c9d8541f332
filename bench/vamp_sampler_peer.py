"""VAMP's RRT-Connect on the MotionBenchMaker problems with each of its two samplers.

Usage: python vamp_sampler_peer.py ROBOT PROBLEMS.pkl
Run with the interpreter of the VAMP peer's virtualenv (`../shared/peers/vamp/side_by_side.sh`
makes it, by default under /tmp/vamp-peer-venv). For each set, plans every valid problem twice
with VAMP's default settings: with the Halton sequence reset per problem (what the peer script
and VAMP's own evaluate_mbm.py use) and with VAMP's xorshift random generator (one stream over
the set, as a random sampler is used). Times cover solved problems only, as the peer script's.
Prints per set and sampler:
  RESULT vamp_sampler set=<set>_<robot> sampler=<halton|xorshift> valid= solved= median_ms= median_iterations=
"""
import pickle
import statistics
import sys

import vamp


def main():
    robot, pkl = sys.argv[1], sys.argv[2]
    problems = pickle.load(open(pkl, "rb"))
    vmod, planner, settings, _ = vamp.configure_robot_and_planner_with_kwargs(robot, "rrtc")
    for sampler_name in ("halton", "xorshift"):
        sampler = vmod.halton() if sampler_name == "halton" else vmod.xorshift()
        for name, pset in problems["problems"].items():
            times, iterations, valid = [], [], 0
            for data in pset:
                if not data["valid"]:
                    continue
                valid += 1
                env = vamp.problem_dict_to_vamp(data)
                if sampler_name == "halton":
                    sampler.reset()
                r = planner(data["start"], data["goals"], env, settings, sampler)
                if r.solved:
                    times.append(r.nanoseconds / 1e6)
                    iterations.append(r.iterations)
            median = statistics.median(times) if times else float("nan")
            median_it = statistics.median(iterations) if iterations else float("nan")
            print(
                f"RESULT vamp_sampler set={name}_{robot} sampler={sampler_name} valid={valid} "
                f"solved={len(times)} median_ms={median:.4f} median_iterations={median_it:.0f}"
            )


if __name__ == "__main__":
    main()
