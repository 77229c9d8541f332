"""Watches a running emberd over Zenoh with the Python `eclipse-zenoh` package: a client no one
on the Ember team wrote. Checks the documented keys and documents (README, "Monitoring").

Usage: python watch_zenoh.py ENDPOINT INSTANCE DAEMON_PID -- CLIENT_COMMAND...

Subscribes to status, plans and liveliness, runs CLIENT_COMMAND (which plans through the daemon's
iceoryx2 services), expects its plans as summaries and in the status, queries the database and
the map, then stops the daemon with SIGTERM and expects its liveliness token to go.
Exits non-zero on any mismatch.
"""
import json
import os
import queue
import signal
import struct
import subprocess
import sys
import time

import zenoh


def wait(q, what, pred, timeout=15.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        try:
            item = q.get(timeout=max(0.01, deadline - time.time()))
        except queue.Empty:
            break
        if pred(item):
            return item
    sys.exit(f"timed out waiting for {what}")


def query_one(session, key):
    for reply in session.get(key, timeout=5.0):
        if reply.ok is not None:
            return reply.ok
    sys.exit(f"no answer on {key}")


def main(endpoint, instance, pid, command):
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps("peer"))
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    session = zenoh.open(conf)
    base = f"ember/{instance}"

    alive, statuses, plans = queue.Queue(), queue.Queue(), queue.Queue()
    session.liveliness().declare_subscriber(
        f"{base}/alive",
        lambda s: alive.put(s.kind == zenoh.SampleKind.PUT),
        history=True,
    )
    session.declare_subscriber(
        f"{base}/status", lambda s: statuses.put(json.loads(s.payload.to_bytes()))
    )
    session.declare_subscriber(
        f"{base}/plans", lambda s: plans.put(json.loads(s.payload.to_bytes()))
    )
    wait(alive, "the liveliness token", lambda up: up)
    first = wait(statuses, "a status", lambda s: True)
    assert first["instance"] == instance and first["dof"] == 8, first
    for section in ("inputs", "map", "world", "experience", "plans", "recording"):
        assert section in first, (section, first)

    subprocess.run(command, check=True)
    summary = wait(plans, "a plan summary", lambda p: p["status_name"] == "ok")
    assert summary["instance"] == instance and summary["waypoints"] >= 2, summary
    status = wait(statuses, "a status counting plans", lambda s: s["plans"]["total"] >= 2)
    assert status["plans"]["solved"] >= 1 and status["plans"]["latency_p50_ms"] > 0, status

    answered = json.loads(query_one(session, f"{base}/status").payload.to_bytes())
    assert answered["instance"] == instance, answered
    db = json.loads(query_one(session, f"{base}/database").payload.to_bytes())
    assert "spark_entries" in db and "flame_entries" in db, db
    raw = query_one(session, f"{base}/map").payload.to_bytes()
    magic, version, resolution, _stamp, count = struct.unpack_from("<8sIfQI", raw, 0)
    assert magic == b"EMBERMAP" and version == 1 and len(raw) == 28 + 20 * count, (magic, version)
    assert abs(resolution - 0.02) < 1e-6, resolution

    os.kill(pid, signal.SIGTERM)
    wait(alive, "the token's withdrawal", lambda up: not up)
    session.close()
    print(
        f"zenoh watch ok: {status['plans']['total']} plans seen, "
        f"p50 {status['plans']['latency_p50_ms']:.2f} ms, map {count} octoboxes"
    )


if __name__ == "__main__":
    if len(sys.argv) < 6 or sys.argv[4] != "--":
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[5:])
