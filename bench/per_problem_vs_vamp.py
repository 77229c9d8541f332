"""Ember's and VAMP's searches on the problems both solve: median iterations and time per iteration.

Usage: python per_problem_vs_vamp.py EMBER.txt VAMP.txt [--truth TRUTH.csv]
EMBER.txt holds `ember-bench plan --per-problem` output (its `PROBLEM set= index= solved=1 ms=
iterations=` lines), VAMP.txt the output of `vamp_problems_peer.py` on the same set (`PROBLEM
set= index= solved= iterations= tree_nodes= us=`). Sets are matched by name without the
`_fetch`/`_panda` suffix. Prints, per set, one line:
  RESULT per_problem_vs_vamp set= common= ember_median_iterations= vamp_median_iterations=
      ember_ns_per_iteration= vamp_ns_per_iteration= ember_median_ms= vamp_median_ms= ratio=
(ns per iteration: total time over total iterations on the common problems; Ember's time is its
planning time, VAMP's its planner call's; the medians and their ratio, Ember / VAMP, are over the
common problems only, where `side_by_side.sh` takes each planner's median over the problems it
solves).
With --truth (a CSV as `../shared/tools/fcl_validity.py` writes, e.g. `target/fcl_truth.csv`
from `ember-bench validity`: start and goal checked on the meshes by FCL, MoveIt's checker), one
more line per set the CSV holds counts the solved problems against that ground truth:
  RESULT solved_vs_truth set= truth_valid= ember_solved_valid= vamp_solved_valid=
      ember_solved_invalid= vamp_solved_invalid=
(`_valid`: solved problems whose start and goal are free on the meshes; `_invalid`: solved
problems whose start or goal is in collision there, paths that begin or end in a contact).
"""
import csv
import re
import statistics
import sys
from collections import defaultdict


def problems(lines, time_key, scale):
    """{set: {index: (iterations, ns)}} of the solved problems in `PROBLEM` lines (a file's, or
    a run's output), each time in `time_key` units × `scale`."""
    out = defaultdict(dict)
    for line in lines:
        if not line.startswith("PROBLEM"):
            continue
        d = dict(re.findall(r"(\w+)=(\S+)", line))
        if d.get("solved") != "1":
            continue
        name = re.sub(r"_(fetch|panda)$", "", d["set"])
        out[name][int(d["index"])] = (int(d["iterations"]), float(d[time_key]) * scale)
    return out


def truth(path):
    """{set: {index: start and goal free}} from an `fcl_validity.py` CSV."""
    out = defaultdict(dict)
    for row in csv.DictReader(open(path)):
        name = re.sub(r"_(fetch|panda)$", "", row["set"])
        out[name][int(row["index"])] = row["start_free"] == "1" and row["goal_free"] == "1"
    return out


def solved_vs_truth(name, ember, vamp, free):
    """The `RESULT solved_vs_truth` line of one set."""
    valid = {k for k, ok in free.items() if ok}
    counts = [len(set(runs) & valid) for runs in (ember, vamp)]
    counts += [len(set(runs) - valid) for runs in (ember, vamp)]
    return (
        f"RESULT solved_vs_truth set={name} truth_valid={len(valid)} "
        f"ember_solved_valid={counts[0]} vamp_solved_valid={counts[1]} "
        f"ember_solved_invalid={counts[2]} vamp_solved_invalid={counts[3]}"
    )


def main():
    ember = problems(open(sys.argv[1]), "ms", 1e6)
    vamp = problems(open(sys.argv[2]), "us", 1e3)
    free = truth(sys.argv[sys.argv.index("--truth") + 1]) if "--truth" in sys.argv else None
    for name in sorted(set(ember) & set(vamp)):
        if free is not None and name in free:
            print(solved_vs_truth(name, ember[name], vamp[name], free[name]))
        common = sorted(set(ember[name]) & set(vamp[name]))
        if not common:
            continue
        e = [ember[name][k] for k in common]
        v = [vamp[name][k] for k in common]
        per = lambda runs: sum(ns for _, ns in runs) / sum(it for it, _ in runs)
        ems = statistics.median(ns for _, ns in e) / 1e6
        vms = statistics.median(ns for _, ns in v) / 1e6
        print(
            f"RESULT per_problem_vs_vamp set={name} common={len(common)} "
            f"ember_median_iterations={statistics.median(i for i, _ in e):.0f} "
            f"vamp_median_iterations={statistics.median(i for i, _ in v):.0f} "
            f"ember_ns_per_iteration={per(e):.1f} vamp_ns_per_iteration={per(v):.1f} "
            f"ember_median_ms={ems:.4f} vamp_median_ms={vms:.4f} ratio={ems / vms:.3f}"
        )


if __name__ == "__main__":
    main()
