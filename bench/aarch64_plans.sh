#!/usr/bin/env bash
# The planner on aarch64 (its lanes in NEON) against x86-64 (AVX2), problem by problem: the
# same `ember-bench plan --per-problem` on both, the aarch64 build run under qemu's user-mode
# emulation, its spheres fitted afresh there (an empty cache). Every PROBLEM line but its
# times must be equal: the same verdicts, iterations, nodes, lengths and waypoints.
#
# Usage (from the project root; .ci/aarch64 installs the target, cross linker and qemu):
#   bench/aarch64_plans.sh DIR... [-- ROBOT_ARGS...]      # ROBOT_ARGS as for ember-bench plan
# Prints per folder, then for all:
#   RESULT aarch64_plans set=<folder|all> problems=<n> identical=<k> differing=<k>
# and exits 1 when any line differs (the first differences printed). qemu runs the planner
# ~100 times slower than the host, so the time limit is raised to 1000 s: a search must not
# end on time on one side only. Times under qemu say nothing about ARM hardware.
set -euo pipefail
cd "$(dirname "$0")/.."
TARGET=aarch64-unknown-linux-gnu
DIRS=()
while [ $# -gt 0 ] && [ "$1" != "--" ]; do DIRS+=("$1"); shift; done
[ "${1:-}" = "--" ] && shift
[ ${#DIRS[@]} -gt 0 ] || { echo "usage: $0 DIR... [-- ROBOT_ARGS...]" >&2; exit 2; }

export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
cargo build -q --release -p ember-bench
cargo build -q --release -p ember-bench --target "$TARGET"
T="${CARGO_TARGET_DIR:-target}"
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
ARGS=(plan --problems "${DIRS[@]}" --per-problem --time-limit 1000 "$@")
"$T/release/ember-bench" "${ARGS[@]}" > "$OUT/x86_64.txt"
EMBER_CACHE_DIR="$OUT/cache" qemu-aarch64 -L /usr/aarch64-linux-gnu \
  "$T/$TARGET/release/ember-bench" "${ARGS[@]}" > "$OUT/aarch64.txt"

# The per-problem lines without their times.
strip() { grep '^PROBLEM' "$1" | sed -E 's/ (ms|total_ms|search_ms)=[0-9.]+//g'; }
strip "$OUT/x86_64.txt" > "$OUT/x86_64.lines"
strip "$OUT/aarch64.txt" > "$OUT/aarch64.lines"
python3 - "$OUT/x86_64.lines" "$OUT/aarch64.lines" <<'EOF'
import sys
from collections import defaultdict
x86, arm = (open(p).read().splitlines() for p in sys.argv[1:3])
if len(x86) != len(arm):
    print(f"{len(x86)} problems on x86-64, {len(arm)} on aarch64", file=sys.stderr)
    sys.exit(1)
sets = defaultdict(lambda: [0, 0])
shown = 0
for a, b in zip(x86, arm):
    name = a.split()[1].removeprefix("set=")
    same = a == b
    sets[name][0 if same else 1] += 1
    if not same and shown < 5:
        print(f"x86-64:  {a}\naarch64: {b}", file=sys.stderr)
        shown += 1
sets["all"] = [sum(v[0] for v in sets.values()), sum(v[1] for v in sets.values())]
for name, (same, other) in sets.items():
    print(f"RESULT aarch64_plans set={name} problems={same + other} identical={same} differing={other}")
sys.exit(1 if sets["all"][1] else 0)
EOF
