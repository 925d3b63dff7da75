"""Launch files, off-robot closed-loop simulation runner and bag tools."""
