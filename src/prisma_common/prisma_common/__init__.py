"""Shared, ROS-free layer of the workspace: names, parameters, message helpers, diagnostics, typestore and bags."""
