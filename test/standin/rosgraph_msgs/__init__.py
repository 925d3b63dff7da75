"""Test stand-in for the rosgraph_msgs interface package (generated from the typestore)."""
