"""Ember's and VAMP's searches on the problems both solve: median iterations and time per iteration.

Usage: python per_problem_vs_vamp.py EMBER.txt VAMP.txt
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
"""
import re
import statistics
import sys
from collections import defaultdict


def problems(path, time_key, scale):
    """{set: {index: (iterations, ns)}} of the solved problems in a file."""
    out = defaultdict(dict)
    for line in open(path):
        if not line.startswith("PROBLEM"):
            continue
        d = dict(re.findall(r"(\w+)=(\S+)", line))
        if d.get("solved") != "1":
            continue
        name = re.sub(r"_(fetch|panda)$", "", d["set"])
        out[name][int(d["index"])] = (int(d["iterations"]), float(d[time_key]) * scale)
    return out


def main():
    ember = problems(sys.argv[1], "ms", 1e6)
    vamp = problems(sys.argv[2], "us", 1e3)
    for name in sorted(set(ember) & set(vamp)):
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
