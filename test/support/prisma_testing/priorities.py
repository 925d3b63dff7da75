"""The test processes' rungs on the priority ladder of prisma_common.scheduling (whose rungs, the
control path's, are what the nodes use): an instrument must see the control path in time without
holding it up, on a machine the test may fill."""
from __future__ import annotations

from prisma_common.scheduling import CONTROL_PATH_NICE

# A test probe that times the control path runs above it (SCHED_FIFO 20), or it would measure its own
# wait for a core (test_launch_two_hosts: /joint_states seen up to 10 s late at the default priority).
PROBE_RT_PRIORITY = 30
# A test process's DDS threads (receive, delivery): level with the control path's niceness, ahead of
# the ordinary processes of a busy machine, so that every sample the graph publishes reaches the
# test's reader history while its Python thread waits for a core. A receive thread kept from running
# lets the socket buffer overflow and the writers' reliable history (10 deep) move on: samples lost,
# not late. The test's Python thread stays at the default, and so do the processes it starts: an
# observer must not outrank the default-priority nodes it observes (tried on SCHED_FIFO 5: it kept up
# with its streams, and a pass beside the load harness failed no fewer tests; docs/performance.md).
TEST_DDS_NICE = CONTROL_PATH_NICE
# A launch test's collector process (prisma_testing.collector): it only appends each sample of the
# streams the test checks to a file, as a recorder on the robot would; on the test DDS threads' rung,
# ahead of the ordinary processes, not real-time: the sim graph takes up to 1.7 of 2 cores at SCHED_FIFO
# 20 on a slow VM, and real-time CPU above it counts against the kernel's 95% real-time budget
# (docs/performance.md, "A collector apart").
TEST_COLLECTOR_NICE = CONTROL_PATH_NICE
# The fault CLI a test runs acts when the test says: above every ordinary process, below the control
# path, which it must not hold up (a default-priority start took 4-15 s on a loaded 2-core machine).
FAULT_CLI_RT_PRIORITY = 10
