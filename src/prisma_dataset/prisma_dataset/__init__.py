"""prisma-dataset: demonstrations recorded as bags, exported as LeRobot v3.0 datasets."""
