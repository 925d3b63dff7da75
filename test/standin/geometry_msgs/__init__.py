"""Test stand-in for the geometry_msgs interface package (generated from the typestore)."""
