"""Helpers shared by every test and by bench/: the ROS harness (ros_harness), the repository's paths
(repo_paths), the topic table (topic_table), the machine load (load_harness), the goal soak
(goal_soak), the two-host rig (two_hosts, host_probe), a test's collector process (collector), the
JSON-line helper process both drive (json_line_process), the operator's glove (operator_glove), the
URDF's forward kinematics (urdf_kinematics) and a virtual display (virtual_display).

Installed by the root pyproject's editable install (`pip install -e .`), so tests, bench scripts and
the subprocesses they start import `prisma_testing.<module>` with nothing added to sys.path."""
