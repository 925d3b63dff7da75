"""The launched hand and glove graphs measured over DDS beside bare rclpy relays (bench/ros_graph.py).

One job per module, lowest first (bench/README.md has the table): facts (what is measured),
processes (start and stop process groups), cpu (/proc CPU and scheduling), control (the bench's own
ROS node), probe (ros2 bag record and reading its bags), stats (latencies, drops, handled scans,
medians), hand / glove / markers / hosts / profile (the runners of each part), report (the
markdown tables and plots of docs/performance.md).
"""
