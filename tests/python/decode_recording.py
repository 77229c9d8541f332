"""Decodes every message of an Ember session recording with the Python `mcap` and
`mcap-ros2-support` packages: readers no one on the Ember team wrote.

Usage: python decode_recording.py FILE.mcap [--killed]
Exits non-zero when a message does not decode or an expected topic is missing. With --killed
the file is one a daemon left when killed with SIGKILL: it must read to its end with chunk CRCs
validated and no exception; only the object updates it was given are expected.
"""
import sys

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

EXPECTED = {
    "/ember/cloud": "sensor_msgs/msg/PointCloud2",
    "/ember/cloud_pose": "geometry_msgs/msg/PoseStamped",
    "/ember/joints": "sensor_msgs/msg/JointState",
    "/ember/objects": "ember_msgs/msg/ObjectUpdate",
    "/ember/plan_request": "ember_msgs/msg/PlanRequest",
    "/ember/plan_response": "ember_msgs/msg/PlanResponse",
    "/ember/plan_trajectory": "trajectory_msgs/msg/JointTrajectory",
}


def main(path, killed=False):
    counts = {}
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert EXPECTED.get(channel.topic) == schema.name, (channel.topic, schema.name)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/ember/cloud":
                assert decoded.width * decoded.height * decoded.point_step == len(decoded.data)
            if channel.topic == "/ember/plan_response" and decoded.status == 0:
                assert len(decoded.path) == decoded.waypoints * decoded.dof > 0
            if channel.topic == "/ember/plan_trajectory":
                points = decoded.points
                assert len(decoded.joint_names) == 8 and len(points) >= 2
                times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in points]
                assert times[0] == 0 and all(a < b for a, b in zip(times, times[1:])), times
                assert all(len(p.positions) == len(p.velocities) == len(p.accelerations) == 8
                           for p in points)
                assert max(abs(v) for v in points[-1].velocities) == 0
            if channel.topic == "/ember/joints":
                assert len(decoded.name) == len(decoded.position) == 8
    expected = ["/ember/objects"] if killed else list(EXPECTED)
    missing = [t for t in expected if t not in counts]
    assert not missing, f"topics missing from {path}: {missing}"
    total = sum(counts.values())
    what = "killed recording" if killed else "recording"
    print(f"{what}: decoded {total} messages on {len(counts)} topics with mcap + mcap-ros2-support: OK")


if __name__ == "__main__":
    main(sys.argv[1], killed="--killed" in sys.argv[2:])
