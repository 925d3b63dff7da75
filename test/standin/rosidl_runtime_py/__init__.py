"""Test stand-in for rosidl_runtime_py (only `utilities` is provided)."""
