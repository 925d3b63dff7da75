"""prisma_teleop: a glove drives the PRISMA hand (hand-pose retargeting, STAG pose grasps)."""
