"""Test stand-in for the builtin_interfaces interface package (generated from the typestore)."""
