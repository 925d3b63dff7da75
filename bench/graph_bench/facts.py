"""What the graph benchmarks measure: the nodes, their relay roles, the topics and the grasp."""
from __future__ import annotations

from prisma_common.hand import FINGERS

HAND_NODES = ("tactile_driver", "force_estimator", "manipulation", "motor_driver")
GLOVE_NODES = ("glove_driver", "glove_perception")
MARKER_TOPIC = "/prisma/tactile_markers"
RELAY_MARKER_TOPIC = "/prisma/relay_markers"
# the relay role standing in for each node (bench/ros_relay.py)
RELAY_ROLE = {"tactile_driver": "sensor", "force_estimator": "force", "manipulation": "manipulation",
              "motor_driver": "motor", "glove_driver": "glove_driver", "glove_perception": "glove_perception"}
MOVE_STATUS = "/prisma/motors/move/_action/status"
MOVE_FEEDBACK = "/prisma/motors/move/_action/feedback"
FINGER_STREAMS = [f"/prisma/{f}/{s}" for f in FINGERS for s in ("taxels", "wrench", "contact")]
HAND_TOPICS = ([f"/prisma/{f}/{s}" for s in ("taxels", "wrench", "contact") for f in FINGERS]
               + ["/joint_states", "/diagnostics", MOVE_STATUS, MOVE_FEEDBACK])
# The graph's nodes take each other's per-hand topics and publish the per-finger ones only while
# someone subscribes: its probe records the per-hand form (the same samples, read back per finger),
# as the graph's own consumers do. The relays have only the per-finger topics.
HAND_STREAMS = {"/prisma/hand/taxels": "taxels", "/prisma/hand/wrench": "wrench", "/prisma/hand/contact": "contact"}
GRAPH_TOPICS = list(HAND_STREAMS) + ["/joint_states", "/diagnostics", MOVE_STATUS, MOVE_FEEDBACK]
# /stag/image is left out: glove_driver draws it only for a subscriber (~2 ms a frame), which the
# probe would then charge to the window whose frames it counts
GLOVE_TOPICS = ["/stag/frame", "/stag/object", "/stag/hand_pose", "/stag/weight"]
GLOVE_RATE_HZ = 7.3  # config/glove_driver.yaml frame_rate_hz, the real glove's readout rate
# thumb_force 0.7 N, not the default 1.0: the sim world's support lets go of the ball once thumb and
# index both press it above 0.6 N for 0.5 s, after which the next grasp finds nothing to close on.
# The fingers phase (whose end sends the MoveMotors goal measured here) is the default one
GRASP = dict(grasp="pinch", finger_force=0.8, thumb_force=0.7, speed_rpm=60.0, timeout=10.0)
OPEN_RPM = 70.0  # config/motor_driver.yaml max_velocities_rpm
