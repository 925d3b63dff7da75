"""Fingertip sensor hub driver: Arduino serial, direct I2C and simulated backends."""
