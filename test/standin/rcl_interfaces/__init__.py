"""Test stand-in for the rcl_interfaces interface package (generated from the typestore)."""
