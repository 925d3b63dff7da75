"""Default topic and action names shared by the nodes, their clients, the bag tools and the recorders.

Per-finger names are patterns: `TAXELS.format(finger="thumb")`. The nodes publish and subscribe the
same names relative (`prisma/<finger>/taxels`), so that a namespace moves them; the bag tools and the
off-robot recorder use these absolute defaults, which is what a node without a namespace publishes.
"""
TAXELS = "/prisma/{finger}/taxels"
WRENCH = "/prisma/{finger}/wrench"
CONTACT = "/prisma/{finger}/contact"
HAND_TAXELS = "/prisma/hand/taxels"
HAND_WRENCH = "/prisma/hand/wrench"
HAND_CONTACT = "/prisma/hand/contact"
JOINT_STATES = "/joint_states"
DIAGNOSTICS = "/diagnostics"
MOVE_MOTORS = "/prisma/motors/move"
TELEOP_TARGETS = "/prisma/teleop/motor_targets"

# Actions, by the names their servers and clients use (relative: a namespace moves them). The goal
# kinds of prisma_manipulation serve the first four, the motor driver the last two.
GRASP_ACTION = "prisma/grasp"
MANIPULATE_ACTION = "prisma/manipulate"
GRIPPER_ACTION = "prisma/gripper_cmd"
TELEOPERATE_ACTION = "prisma/teleoperate"
MOVE_MOTORS_ACTION = "prisma/motors/move"
HOME_MOTORS_ACTION = "prisma/motors/home"


def relative(name: str) -> str:
    """The name a node uses for the absolute default `name` ("/prisma/teleop/motor_targets" ->
    "prisma/teleop/motor_targets"), so that its namespace moves it."""
    return name.lstrip("/")
