"""ROS-free hand simulator: optical pad model, calibration sets, contact sources, hand/world model."""
