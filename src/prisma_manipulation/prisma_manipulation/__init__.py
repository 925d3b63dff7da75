"""Contact monitor, grasp and in-hand manipulation controllers, the manipulation node and the off-robot closed loop."""
