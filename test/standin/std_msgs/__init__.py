"""Test stand-in for the std_msgs interface package (generated from the typestore)."""
