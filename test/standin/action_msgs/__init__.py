"""Test stand-in for the action_msgs interface package (generated from the typestore)."""
