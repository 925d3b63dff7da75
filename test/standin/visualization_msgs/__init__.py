"""Test stand-in for the visualization_msgs interface package (generated from the typestore)."""
