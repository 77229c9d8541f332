"""VAMP and `ember-bench plan` taking turns, set by set, for several rounds: ratios that the
machine's changes of speed move less.

Usage (from the project root, after `cargo build --release -p ember-bench`):
  python3 bench/interleaved_vs_vamp.py [--robot fetch|panda] [--rounds N] [--sets A,B]
      [--vamp-python PY] [--pointcloud] [-- EMBER_BENCH_PLAN_ARGS...]
`side_by_side.sh` runs VAMP on every set, then Ember on every set, minutes apart; on a machine
whose speed moves from minute to minute (this project's VMs) one planner can be timed in a
slow phase and the other in a fast one. Here each set is planned by VAMP and by Ember back to
back (seconds apart), the one going first alternating from round to round, and every round
gives its own ratio. VAMP runs through `bench/vamp_problems_peer.py` (its default settings, the
Halton sequence reset per problem, as `side_by_side.sh`'s peer script), with the interpreter of
the peer's virtualenv (`--vamp-python`, default /tmp/vamp-peer-venv/bin/python, which
`side_by_side.sh` makes). Medians as `side_by_side.sh` takes them: VAMP's over the problems it
solves, Ember's `median_ms`. Arguments after `--` go to `ember-bench plan` (as for
`side_by_side.sh`: `--robot FILE.urdf --srdf ... --package-path ...`, `--seed S`). With
`--pointcloud`, VAMP plans against its CAPT clouds (`vamp_problems_peer.py --pointcloud`) and
Ember, given `-- --clouds DIR` (the clouds `side_by_side.sh --pointcloud` wrote, by default
/tmp/ember-vs-vamp/clouds), against the same clouds.
Prints, per set and round:
  RESULT interleaved set=<folder> round=<r> vamp_solved= ours_solved= vamp_median_ms=
      ours_median_ms= ratio=
and per set:
  RESULT interleaved_summary set=<folder> rounds= ratio_median= ratio_min= ratio_max=
      vamp_best_median_ms= ours_best_median_ms= best_ratio=
(ratio = ours / VAMP median planning time; `_best_`: the median over the problems each solves
in every round of the problem's fastest time in the rounds. Both planners are deterministic
here, so every round plans the same searches: the fastest of them is the one the machine
slowed least, and between a problem's rounds the other problems of the set have run.)
"""
import os
import re
import statistics
import subprocess
import sys

from per_problem_vs_vamp import problems

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.join(HERE, "..", "..", "shared")


def per_problem(lines, time_key, scale):
    """{index: ms} of the solved problems in one set's `PROBLEM` lines (`time_key` in ms ×
    `scale`), read by `per_problem_vs_vamp.problems`."""
    out = {}
    for runs in problems(lines, time_key, scale * 1e6).values():
        out.update({k: ns / 1e6 for k, (_, ns) in runs.items()})
    return out


def ember_median(lines):
    """(solved, median_ms) from the `RESULT plan` line of `ember-bench plan` output."""
    for line in lines:
        if line.startswith("RESULT plan "):
            d = dict(re.findall(r"(\w+)=(\S+)", line))
            return int(d["solved"]), float(d["median_ms"])
    raise SystemExit("ember-bench plan printed no RESULT plan line")


def best_median(passes):
    """The median over problems of each problem's fastest time in `passes` (dicts {index: ms}),
    over the problems solved in every pass."""
    common = set.intersection(*(set(p) for p in passes))
    return statistics.median(min(p[k] for p in passes) for k in common)


def summary(folder, ratios, vamp_passes, ember_passes):
    """The `RESULT interleaved_summary` line of one set."""
    vb, eb = best_median(vamp_passes), best_median(ember_passes)
    return (
        f"RESULT interleaved_summary set={folder} rounds={len(ratios)} "
        f"ratio_median={statistics.median(ratios):.3f} ratio_min={min(ratios):.3f} "
        f"ratio_max={max(ratios):.3f} vamp_best_median_ms={vb:.4f} "
        f"ours_best_median_ms={eb:.4f} best_ratio={eb / vb:.3f}"
    )


def main():
    args = sys.argv[1:]
    extra = args[args.index("--") + 1 :] if "--" in args else []
    args = args[: args.index("--")] if "--" in args else args
    opt = lambda name, default: args[args.index(name) + 1] if name in args else default
    robot = opt("--robot", "fetch")
    rounds = int(opt("--rounds", "3"))
    vamp_python = opt("--vamp-python", "/tmp/vamp-peer-venv/bin/python")
    root = os.path.join(SHARED, "benchmarks", "mbm", robot)
    pkl = os.path.join(SHARED, "peers", "vamp", "problems", f"{robot}.pkl")
    folders = sorted(os.listdir(root))
    if "--sets" in args:
        wanted = opt("--sets", "").split(",")
        folders = [f for f in folders if re.sub(r"_(fetch|panda)$", "", f) in wanted]
    bench = os.path.join(HERE, "..", "target", "release", "ember-bench")
    for path, how in [(vamp_python, "run ../shared/peers/vamp/side_by_side.sh once to make it"),
                      (bench, "cargo build --release -p ember-bench")]:
        if not os.path.exists(path):
            raise SystemExit(f"{path} is missing: {how}")
    ember_robot = [] if "--robot" in extra else ["--robot", robot]
    for folder in folders:
        name = re.sub(r"_(fetch|panda)$", "", folder)
        # The problems the folder holds (VAMP's pickle has every problem of the set).
        files = os.listdir(os.path.join(root, folder))
        indices = ",".join(str(int(m[1])) for f in files if (m := re.match(r"request(\d+)\.yaml$", f)))
        vamp_cmd = [vamp_python, os.path.join(HERE, "vamp_problems_peer.py"), robot, pkl, name, indices]
        if "--pointcloud" in args:
            vamp_cmd.append("--pointcloud")
        ember_cmd = [bench, "plan", "--problems", os.path.join(root, folder), "--per-problem"]
        ember_cmd += ember_robot + extra
        ratios, vamp_passes, ember_passes = [], [], []
        for r in range(1, rounds + 1):
            out = {}
            # The one going first alternates, so a drift of the machine's speed favours neither.
            order = [("vamp", vamp_cmd), ("ember", ember_cmd)]
            for who, cmd in order if r % 2 else order[::-1]:
                run = subprocess.run(cmd, capture_output=True, text=True, check=True)
                out[who] = run.stdout.splitlines()
            vamp = per_problem(out["vamp"], "us", 1e-3)
            vamp_passes.append(vamp)
            ember_passes.append(per_problem(out["ember"], "ms", 1.0))
            vm = statistics.median(vamp.values())
            es, em = ember_median(out["ember"])
            ratios.append(em / vm)
            print(
                f"RESULT interleaved set={folder} round={r} vamp_solved={len(vamp)} "
                f"ours_solved={es} vamp_median_ms={vm:.4f} ours_median_ms={em:.4f} "
                f"ratio={em / vm:.3f}",
                flush=True,
            )
        print(summary(folder, ratios, vamp_passes, ember_passes), flush=True)


if __name__ == "__main__":
    main()
