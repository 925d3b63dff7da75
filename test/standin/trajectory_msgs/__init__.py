"""Test stand-in for the trajectory_msgs interface package (generated from the typestore)."""
