"""Parameters of the policy node (= config/policy.yaml): the model file, the rate it acts at and how old
an input sample may be. All read-only: a new model or rate is a restart."""
from __future__ import annotations

from dataclasses import dataclass

from prisma_common.parameters import Params, parameter


@dataclass
class PolicyConfig(Params):
    model_path: str = parameter("", "the policy's model file (prisma-policy train --out); \"\" = no model: the node "
                                    "publishes nothing and says so")
    rate_hz: float = parameter(0.0, "how often the policy acts; 0 = the fps of the dataset it learnt from", unit="Hz",
                               bounds=(0.0, 1000.0))
    # 0.15 s: the Teleoperate goal's default input timeout (manipulation teleop_input_timeout), after which the
    # hand stops anyway; at 0.1 s the sim hand's taxels arrived too old on every few ticks on a loaded 2-core
    # machine (test_launch_policy), and the goal ended input_stale again and again
    max_input_age: float = parameter(0.15, "the newest taxels, wrench or joint_states sample older than this on a "
                                           "tick (by its stamp, on this node's clock): the policy holds, nothing is "
                                           "published (the Teleoperate goal then stops the hand, input_stale)",
                                      unit="s", bounds=(0.0, 10.0), open_low=True)
