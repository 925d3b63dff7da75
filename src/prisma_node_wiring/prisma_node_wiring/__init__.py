"""The rclpy wiring every node of the workspace shares: the node process (`run_node`) and the
sample-stream publishers and subscriptions. Node files import it; nothing ROS-free does."""
