"""Test stand-in for the nav_msgs interface package (generated from the typestore)."""
