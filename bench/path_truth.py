"""Planners' returned paths checked on the robot's meshes by FCL (what MoveIt checks with).

Usage: python path_truth.py --urdf U --srdf S --mesh-dir M --problems ROOT [--step D]
           [--fcl-tool PATH] PATHS.jsonl...
Run with an interpreter that has python-fcl, trimesh and PyYAML (the one `fcl_validity.py`
asks for). PATHS holds one JSON object a line, {"set", "index", "joints", "path"} and optionally
"continuous" (joints whose edges go the short way round, as the planner's model has them), as
`ember-bench plan --paths-out` and `vamp_paths_peer.py --dump` write them; ROOT holds the
MotionBenchMaker problem folders named as the sets. Each path's edges are cut into straight
pieces at most D apart (configuration-space Euclidean distance, default 0.01), and every state, waypoints included, is checked with FCL on the URDF's
collision meshes against the problem's scene objects and for the SRDF's enabled self-collision
pairs (`../shared/tools/fcl_validity.py`'s robot, scene and joint-value rules: joints outside the
path take the request's start values). Prints one line per path that touches something,
  TOUCH file= set= index= at=start|goal|between state=<k> of=<n> touching_states=<m>
        contact=<link|object or self:a|b>
(the first state in contact, the states checked, how many of them touch, the first contact)
then per file and set
  RESULT path_truth file= set= paths= touching= between= states= skipped=
(`between`: paths whose start and goal are free on the meshes but a state between them is not;
`skipped`: paths of problems ROOT does not hold).
"""
import argparse
import collections
import importlib.util
import json
import math
import os
import sys

import fcl
import numpy as np


def load_tool(path):
    spec = importlib.util.spec_from_file_location("fcl_validity", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class Checker:
    """One problem's scene and the robot, checked state by state."""

    def __init__(self, tool, model, robot, scene, request):
        self.tool, self.model, self.robot = tool, model, robot
        sjs = (scene.get("robot_state") or {}).get("joint_state") or {}
        scene_q = {n: float(v) for n, v in zip(sjs.get("name") or [], sjs.get("position") or [])}
        self.world = tool.scene_objects(scene, model, model.fk(scene_q))
        # The Panda's requests place the root by a virtual joint at the origin: nothing to do.
        start = request.get("start_state") or {}
        mdof = start.get("multi_dof_joint_state") or {}
        identity = {"rotation": [0, 0, 0, 1], "translation": [0, 0, 0]}
        if all(t == identity for t in mdof.get("transforms") or []):
            start.pop("multi_dof_joint_state", None)
        self.base, _ = tool.request_configs(model, request, {})
        self.manager = fcl.DynamicAABBTreeCollisionManager()
        self.manager.registerObjects([o for _, o in self.world])
        self.manager.setup()
        self.links = fcl.DynamicAABBTreeCollisionManager()
        self.links.registerObjects([o for _, _, o in robot.objs])
        self.links.setup()

    def contact(self, q):
        """The first contact at joint values `q` (dict), or ''."""
        self.robot.set_config(q)
        self.links.update()
        data = fcl.CollisionData()
        self.links.collide(self.manager, data, fcl.defaultCollisionCallback)
        if data.result.is_collision:
            # Which pair, for the report: the broad phase does not name it.
            for link, _, ro in self.robot.objs:
                for oid, wo in self.world:
                    if self.tool.collides(ro, wo):
                        return "%s|%s" % (link, oid)
            return "world"
        for a, b in self.robot.self_pairs:
            if self.tool.collides(self.robot.objs[a][2], self.robot.objs[b][2]):
                return "self:%s|%s" % (self.robot.objs[a][0], self.robot.objs[b][0])
        return ""


def states(path, continuous, step):
    """The path's waypoints and the states between them, at most `step` apart."""
    out = [np.asarray(path[0], float)]
    for a, b in zip(path, path[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = b - a
        for k in continuous:
            d[k] = math.remainder(d[k], 2 * math.pi)
        n = max(1, math.ceil(np.linalg.norm(d) / step))
        for i in range(1, n + 1):
            out.append(a + d * (i / n))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--urdf", required=True)
    ap.add_argument("--srdf", required=True)
    ap.add_argument("--mesh-dir", required=True)
    ap.add_argument("--problems", required=True, help="folder holding the problem folders")
    ap.add_argument("--step", type=float, default=0.01)
    ap.add_argument("--fcl-tool", default="../shared/tools/fcl_validity.py")
    ap.add_argument("paths", nargs="+")
    args = ap.parse_args()
    tool = load_tool(args.fcl_tool)
    model = tool.URDFModel(args.urdf, args.mesh_dir)
    robot = tool.RobotCollision(model, tool.parse_srdf_disabled(args.srdf))
    for file in args.paths:
        tally = collections.OrderedDict()
        skipped = collections.Counter()
        for line in open(file):
            rec = json.loads(line)
            folder = os.path.join(args.problems, rec["set"])
            index = int(rec["index"])
            if not os.path.isfile(os.path.join(folder, "scene%04d.yaml" % index)):
                # A peer's pickle may hold problems the folders do not (the Fetch's even half).
                skipped[rec["set"]] += 1
                continue
            scene = tool.load_yaml(os.path.join(folder, "scene%04d.yaml" % index))
            request = tool.load_yaml(os.path.join(folder, "request%04d.yaml" % index))
            checker = Checker(tool, model, robot, scene, request)
            joints = rec["joints"]
            wraps = set(rec.get("continuous", []))
            continuous = [k for k, n in enumerate(joints) if n in wraps]
            qs = states(rec["path"], continuous, args.step)
            t = tally.setdefault(rec["set"], [0, 0, 0, 0])
            t[0] += 1
            t[3] += len(qs)
            hits = []
            for k, v in enumerate(qs):
                q = dict(checker.base)
                q.update(zip(joints, map(float, v)))
                c = checker.contact(q)
                if c:
                    hits.append((k, c))
            if not hits:
                continue
            k, c = hits[0]
            ends = {0, len(qs) - 1} & {h for h, _ in hits}
            at = "start" if 0 in ends else "goal" if ends else "between"
            t[1] += 1
            t[2] += at == "between"
            print("TOUCH file=%s set=%s index=%d at=%s state=%d of=%d touching_states=%d contact=%s" % (
                os.path.basename(file), rec["set"], index, at, k, len(qs), len(hits), c), flush=True)
        for name, (n, touching, between, count) in tally.items():
            print("RESULT path_truth file=%s set=%s paths=%d touching=%d between=%d states=%d "
                  "skipped=%d" % (os.path.basename(file), name, n, touching, between, count,
                                  skipped[name]), flush=True)


if __name__ == "__main__":
    sys.exit(main())
