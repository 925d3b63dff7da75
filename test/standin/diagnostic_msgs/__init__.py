"""Test stand-in for the diagnostic_msgs interface package (generated from the typestore)."""
