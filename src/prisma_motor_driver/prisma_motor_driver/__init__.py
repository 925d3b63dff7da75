"""Dynamixel and simulated motors: codec, bus, emulator, motor driver core and node."""
