"""prisma-sim: the off-robot closed-loop sessions on the nodes' own cores, recorded as bags and plots."""
