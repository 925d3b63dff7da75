"""Test stand-in for the sensor_msgs interface package (generated from the typestore)."""
