"""Dynamixel and simulated motors, contact monitor, grasp and in-hand manipulation controllers."""
