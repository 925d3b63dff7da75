"""Launch files, node configuration and model bundles, and prisma-doctor (the bring-up check)."""
