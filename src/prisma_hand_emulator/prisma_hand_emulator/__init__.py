"""The PRISMA hand's hardware emulated in one process (hardware:=emulated), and its fault CLI."""
