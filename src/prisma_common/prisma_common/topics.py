"""Default topic names shared by the nodes' converters, the bag tools and the recorders.

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
