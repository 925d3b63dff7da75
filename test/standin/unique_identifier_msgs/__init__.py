"""Test stand-in for the unique_identifier_msgs interface package (generated from the typestore)."""
