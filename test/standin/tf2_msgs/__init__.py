"""Test stand-in for the tf2_msgs interface package (generated from the typestore)."""
