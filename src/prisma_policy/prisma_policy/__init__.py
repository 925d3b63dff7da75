"""prisma_policy: a behaviour-cloning policy learned from prisma-dataset LeRobot datasets."""
