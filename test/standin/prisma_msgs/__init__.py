"""Test stand-in for the prisma_msgs interface package (generated from the typestore)."""
